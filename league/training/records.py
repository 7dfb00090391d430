"""What one training iteration produced, read once into typed records.

``TrainResult`` is ``algo.train()``'s result dict as the league reads it (through
``league.rllib.bridge``'s readers, the only code that knows its keys); ``IterationRecord`` is
the whole iteration, which the coordinator commits to the store (``Coordinator.commit``) and the
progress line reports (``ProgressReporter.iteration``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, TypeVar

from league.core.payoff import OutcomeCount
from league.core.players import NewPlayer, Player
from league.core.schedule import PhaseState

if TYPE_CHECKING:
    from league.evaluation.engine import PairEvaluation
    from league.evaluation.learning_curves import Measurements

T = TypeVar("T")


def timed(call: Callable[[], T]) -> tuple[T, float]:
    """``call()``'s result and its wall-clock seconds."""
    started = time.perf_counter()
    result = call()
    return result, time.perf_counter() - started


@dataclass(frozen=True)
class IterationTiming:
    """Wall-clock seconds of one iteration's parts."""

    sampling: float  # ``algo.train()`` minus the Learner's updates
    learning: float  # the Learner's updates
    evaluation: float  # in-training evaluation of the learners (0 when none was due)


@dataclass(frozen=True)
class TrainResult:
    """One ``algo.train()``: the outcomes of the episodes that ended in it, by player; its env steps;
    per trainee module its env steps, mean episode return and the Learner's statistics."""

    outcomes: list[OutcomeCount]
    sampled_env_steps: int  # the run's env steps sampled so far (RLlib's lifetime count)
    trainee_steps: dict[str, int]  # env steps of each trainee's games in this call
    returns: dict[str, float]  # mean episode return of each trainee that finished episodes
    learner_stats: dict[str, dict[str, Any]]  # the Learner's results (losses, entropy, KL) per trained module
    seconds: float  # wall time of ``algo.train()``
    learning_seconds: float  # the Learner's own clock of its updates

    @staticmethod
    def read(result: dict[str, Any], players: list[Player], seconds: float, learning_seconds: float) -> TrainResult:
        from league.rllib import bridge  # (here: importing it imports RLlib)

        attackers: dict[str, Player] = {}
        teams: dict[tuple[str, str], Player] = {}
        for player in players:
            modules = player.modules()
            if player.side == "attacker":
                attackers[modules["attacker"]] = player
            else:
                teams[(modules["targeter"], modules["defender"])] = player
        outcomes = [
            OutcomeCount(attackers[attacker].id, teams[(targeter, defender)].id, outcome, count)
            for (attacker, targeter, defender), outcome, count in bridge.episode_outcomes(result)
        ]
        trainees = [p for p in players if p.trains]
        names = [p.name for p in trainees]
        return TrainResult(
            outcomes, bridge.sampled_env_steps(result), bridge.learner_env_steps(result, trainees),
            bridge.module_returns(result, names), bridge.learner_stats(result, names), seconds, learning_seconds,
        )


@dataclass(frozen=True)
class IterationRecord:
    """One iteration, as committed and reported."""

    iteration: int
    phase: PhaseState  # the phase it trained in, as it stood after it (before a phase change)
    train: TrainResult
    steps: int  # env steps sampled in this iteration
    env_steps: int  # in all so far
    episodes: int  # in all so far
    snapshots: list[NewPlayer]  # trainees frozen at the phase's end
    snapshot_names: list[str]  # as the progress line names them
    evaluation: list[PairEvaluation]  # pairs evaluated during the iteration
    curves: Measurements  # learning-curve points measured after it
    weights: dict[str, dict[str, float]]  # each learner's probability per opponent
    timing: IterationTiming
    league_size: int  # members once its snapshots joined
    checkpoint: Path | None  # its checkpoint directory, when one was written
