"""What a running league shows: one line per iteration and TensorBoard scalars.

On a terminal the lines go through rich (time column, colours); otherwise (a log file,
a pipe) each iteration is one plain line, ``HH:MM:SS text``, so that ``grep`` finds it whole.

Every figure is this iteration's own, measured here: steps per second are the env steps
sampled in the iteration divided by the wall time of ``algo.train()`` (sampling and
learning together); the split is the Learner's own clock of its updates (learning) and
the rest of ``algo.train()`` (sampling, weight sync), plus the in-training evaluation.
RLlib's result timers are exponential averages over iterations and are not used.

Where every phase has an env-step budget, the line also says how much of the run's whole budget is
done and the time left (``budget_left``); the speed behind it is the one exception to "this
iteration's own": it is averaged over the last ``ETA_WINDOW`` iterations of this process.
"""

from __future__ import annotations

import sys
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np
from rich.console import Console
from tensorboardX import SummaryWriter

if TYPE_CHECKING:
    from league.core.schedule import PhaseState
    from league.evaluation.engine import PairEvaluation
    from league.training.records import IterationRecord

TRAIN_METRICS = ("policy_loss", "vf_loss", "entropy", "mean_kl_loss")


@dataclass
class TimeSplit:
    """Where one process's wall time went: training iterations (``algo.train()``), the
    evaluations during training (learning curves, pool evaluations) and the final evaluation."""

    training: float = 0.0
    evaluation: float = 0.0
    final_evaluation: float = 0.0

    def summary(self, total: float) -> str:
        """``total`` seconds split into the three parts and the rest, with each part's share."""
        parts = [("training iterations", self.training), ("evaluations during training", self.evaluation),
                 ("final evaluation", self.final_evaluation)]
        parts.append(("the rest", max(0.0, total - sum(seconds for _, seconds in parts))))
        return ", ".join(f"{name} {seconds:.0f} s ({100 * seconds / max(total, 1e-9):.0f}%)" for name, seconds in parts)


def budget_left(done: int, budget: int, steps_per_second: float) -> str:
    """``done`` of ``budget`` env steps as a share, and the time left at ``steps_per_second``:
    ``42% of 5,013,504, 3 min left`` (no time left where the speed is not known yet)."""
    share = f"{100 * min(done, budget) / budget:.0f}% of {budget:,}"
    if not steps_per_second > 0:  # (also NaN)
        return share
    return f"{share}, {duration(max(0, budget - done) / steps_per_second)} left"


def duration(seconds: float) -> str:
    """``40 s``, ``12 min``, ``3 h 05 min``: as coarse as a time left is worth reading."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    minutes = round(seconds / 60)
    return f"{minutes} min" if minutes < 90 else f"{minutes // 60} h {minutes % 60:02d} min"


ETA_WINDOW = 10  # iterations whose average speed gives the time left


class BudgetClock:
    """How far a run is through its phases' env-step budgets, and its recent speed through them.

    Done is every earlier phase's whole budget (a self-play phase that ended on its win rate used
    up its budget: the rest is not to be played) and the current phase's env steps. The speed is
    the phase's env steps (those that count against its budget: not a learner phase's exploiters')
    over wall time, averaged over the last ``ETA_WINDOW`` iterations: each iteration from the
    previous line to its own, and the first after a start or resume, which has no previous line,
    its own clocked time and env steps."""

    def __init__(self, phase_budgets: list[int]):
        self.phase_budgets = phase_budgets
        self.budget = sum(phase_budgets)
        self.recent: deque[tuple[float, int]] = deque(maxlen=ETA_WINDOW)  # (seconds, phase env steps) per iteration
        self.last: tuple[float, "PhaseState"] | None = None  # the previous line's clock and phase

    def done(self, phase: "PhaseState") -> int:
        return sum(self.phase_budgets[:phase.index]) + min(phase.env_steps, self.phase_budgets[phase.index])

    def line(self, phase: "PhaseState", steps: int, seconds: float, now: float) -> str:
        """``budget_left`` after an iteration that ended with ``phase``; ``steps`` and ``seconds`` are
        the iteration's own env steps and clocked time, used when there is no previous line."""
        if self.last is None:
            counted = min(steps, phase.env_steps)
        else:
            seconds, last_phase = now - self.last[0], self.last[1]
            counted = phase.env_steps - last_phase.env_steps if last_phase.index == phase.index else phase.env_steps
        self.last = (now, phase)
        self.recent.append((seconds, counted))
        elapsed = sum(s for s, _ in self.recent)
        speed = sum(n for _, n in self.recent) / elapsed if elapsed > 0 else float("nan")
        return budget_left(self.done(phase), self.budget, speed)


LOG_FILE = "run.log"  # in the run directory: the progress lines of every process that trained it


class ProgressReporter:
    def __init__(self, run_dir: Path, total_phases: int, stream: IO[str] | None = None, phase_budgets: list[int] | None = None):
        """``phase_budgets``: each phase's env-step budget (``Schedule.env_step_budgets``); None
        (a phase that ends after its episodes): the lines say no share or time left."""
        self.stream = stream or sys.stderr
        self.console = Console(file=self.stream, log_path=False) if self.stream.isatty() else None
        self.writer = SummaryWriter(str(run_dir / "tensorboard"))
        self.log = open(run_dir / LOG_FILE, "a")  # every line also here, a resume's after the run's before
        self.total_phases = total_phases
        self.budget = BudgetClock(phase_budgets) if phase_budgets else None

    def close(self) -> None:
        self.writer.close()
        self.log.close()

    def message(self, text: str) -> None:
        line = f"{time.strftime('%Y-%m-%d %H:%M:%S')} {text}"
        self.log.write(line + "\n")
        self.log.flush()
        if self.console is not None:
            self.console.log(text, markup=False, highlight=False)
        else:
            print(f"{time.strftime('%H:%M:%S')} {text}", file=self.stream, flush=True)

    def iteration(self, record: "IterationRecord") -> None:
        """Report one iteration: its line, and its scalars against the run's env steps.

        The phase is as it stood after the iteration (before a phase change); the speed is the
        iteration's env steps over its sampling and learning."""
        phase, timing, evaluation, env_steps = record.phase, record.timing, record.evaluation, record.env_steps
        phase_rate = phase.learner_wins / phase.episodes if phase.episodes else float("nan")
        side = phase.side
        train_seconds = timing.sampling + timing.learning
        steps_per_second = record.steps / train_seconds if train_seconds > 0 else float("nan")
        evaluated = f", eval {timing.evaluation:.1f} s" if evaluation or timing.evaluation >= 0.05 else ""  # or curves
        budget = "" if self.budget is None else " | " + self.budget.line(
            phase, record.steps, train_seconds + timing.evaluation, time.monotonic())
        self.message(
            f"phase {phase.index + 1}/{self.total_phases} {side:8s} | iter {record.iteration:4d} | "
            f"{env_steps:8d} env steps in all | {steps_per_second:6.0f} steps/s | "
            f"sample {timing.sampling:.1f} s, learn {timing.learning:.1f} s{evaluated} | "
            f"{side} win rate {phase_rate:.2f} over {phase.episodes} ep | league {record.league_size}{budget}"
            + (f" | snapshot {', '.join(record.snapshot_names)}" if record.snapshot_names else "")
        )
        i = env_steps  # TensorBoard's x axis: env steps, which runs of other batch sizes share; not iterations
        self.scalar("perf/sps", steps_per_second, i)
        self.scalar("perf/iteration", record.iteration, i)
        self.scalar("perf/sampling_seconds", timing.sampling, i)
        self.scalar("perf/learning_seconds", timing.learning, i)
        if evaluation:
            self.scalar("perf/evaluation_seconds", timing.evaluation, i)
        self.scalar("league/size", record.league_size, i)
        self.scalar("league/phase", phase.index, i)
        self.scalar(f"league/{side}_phase_win_rate", phase_rate, i)
        for learner, opponents in record.weights.items():
            for opponent, p in opponents.items():
                self.scalar(f"league/pfsp/{learner}/{opponent}", p, i)
        for module, stats in record.train.learner_stats.items():
            for key in TRAIN_METRICS:
                self.scalar(f"train/{module}/{key}", stats.get(key), i)
        self.evaluation(evaluation, i)
        self.writer.flush()

    def evaluation(self, results: list["PairEvaluation"], env_steps: int) -> None:
        """Attacker win rate of each evaluated pair, ``eval/ATTACKER_vs_TEAM``, at ``env_steps`` of the run."""
        for r in results:
            self.scalar(f"eval/{r.attacker.name}_vs_{r.team.name}", r.attacker_wins / r.games, env_steps)

    def scalar(self, tag: str, value: Any, step: int) -> None:
        """Write a scalar unless it is missing or not finite (an empty phase, an idle module)."""
        try:
            value = float(value)
        except (TypeError, ValueError):
            return
        if np.isfinite(value):
            self.writer.add_scalar(tag, value, step)
