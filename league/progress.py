"""What a running league shows: one line per iteration (rich) and TensorBoard scalars.

Steps per second are env steps sampled in the iteration divided by its wall time,
sampling and learning together.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from rich.console import Console
from tensorboardX import SummaryWriter


if TYPE_CHECKING:
    from league.coordinator import Coordinator

TRAIN_METRICS = ("policy_loss", "vf_loss", "entropy", "mean_kl_loss")


class ProgressReporter:
    def __init__(self, run_dir: Path, total_phases: int, console: Console | None = None):
        self.console = console or Console(stderr=True)
        self.writer = SummaryWriter(str(run_dir / "tensorboard"))
        self.total_phases = total_phases

    def close(self) -> None:
        self.writer.close()

    def message(self, text: str) -> None:
        self.console.log(text)

    def iteration(
        self,
        coordinator: "Coordinator",
        result: dict[str, Any],
        weights: dict[str, dict[str, float]],
        steps_per_second: float,
        snapshots: list[str],
    ) -> None:
        st = coordinator.state
        phase = st.phase
        league_size = len(coordinator.store.players())
        phase_rate = phase.learner_wins / phase.episodes if phase.episodes else float("nan")
        side = phase.side
        self.console.log(
            f"phase {phase.index + 1}/{self.total_phases} {side:8s} | iter {st.iteration:4d} | "
            f"{st.env_steps:8d} env steps | {steps_per_second:6.0f} steps/s | "
            f"{side} win rate {phase_rate:.2f} over {phase.episodes} ep | league {league_size}"
            + (f" | snapshot {', '.join(snapshots)}" if snapshots else "")
        )
        i = st.iteration
        self.scalar("perf/sps", steps_per_second, i)
        self.scalar("perf/env_steps", st.env_steps, i)
        self.scalar("league/size", league_size, i)
        self.scalar("league/phase", phase.index, i)
        self.scalar(f"league/{side}_phase_win_rate", phase_rate, i)
        for learner, opponents in weights.items():
            for opponent, p in opponents.items():
                self.scalar(f"league/pfsp/{learner}/{opponent}", p, i)
        learner_names = {p.name for p in coordinator.store.players(kind="learner")}
        for module, stats in result.get("learners", {}).items():
            if module in learner_names:
                for key in TRAIN_METRICS:
                    self.scalar(f"train/{module}/{key}", stats.get(key), i)
        self.writer.flush()

    def scalar(self, tag: str, value: Any, step: int) -> None:
        """Write a scalar unless it is missing or not finite (an empty phase, an idle module)."""
        try:
            value = float(value)
        except (TypeError, ValueError):
            return
        if np.isfinite(value):
            self.writer.add_scalar(tag, value, step)
