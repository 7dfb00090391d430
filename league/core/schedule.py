"""The league's schedule: which side learns in each phase, against whom, and when a phase ends.

| schedule  | phases                         | a phase's opponents                               | a phase ends                     |
| --------- | ------------------------------ | ------------------------------------------------- | -------------------------------- |
| protocol  | ``league.phases``, in order    | the other side's scripted players, its newest     | after the phase's ``episodes``   |
|           |                                | snapshot (``opponents: latest``), or both         | (or ``env_steps``)               |
|           |                                | (``scripted_and_latest``), or the scripted players|                                  |
|           |                                | and every snapshot (``scripted_and_snapshots``)   |                                  |
| self-play | ``selfplay_phases``, attacker  | every scripted player and snapshot of the other   | the learner won                  |
|           | first, then in turn            | side                                              | ``snapshot_win_rate`` of at least|
|           |                                |                                                   | ``min_phase_episodes``, or after |
|           |                                |                                                   | ``phase_env_steps``              |

A side's pool holds its exploiters' snapshots too (``league.exploiters``); the exploiters
themselves play in their side's phases against the other side's newest snapshots only,
and their games do not count in ``PhaseState`` (``League.count_played``). With
``league.exploiter_phases: final`` they train only in one more phase after the self-play
phases, alone: its ``PhaseState`` counts their games (``trainee_kinds``).

``PhaseState`` is a phase's progress, kept by the coordinator in its resume state.
"""

from __future__ import annotations

from dataclasses import dataclass

from league.config import LeagueSettings, RunConfig
from league.core.players import Player, Side


@dataclass
class PhaseState:
    index: int
    side: Side
    start_iteration: int
    episodes: int = 0
    learner_wins: int = 0
    env_steps: int = 0


class ProtocolSchedule:
    """The paper's protocol: the configured phases in order."""

    def __init__(self, league: LeagueSettings):
        self.league = league
        self.phases = len(league.phases)

    def side(self, index: int) -> Side:
        return self.league.phases[index].learner

    def trainee_kinds(self, index: int) -> tuple[str, ...]:
        """The kinds of player that train in a phase, the first the one whose games end it."""
        return ("learner",)

    def opponents(self, index: int, scripted: list[Player], snapshots: list[Player]) -> list[Player]:
        spec = self.league.phases[index]
        if spec.opponents == "scripted":
            return scripted
        if not snapshots:
            raise RuntimeError(f"phase {spec} wants the latest snapshot of the other side, but there is none")
        if spec.opponents == "scripted_and_snapshots":
            return scripted + snapshots
        return [snapshots[-1]] if spec.opponents == "latest" else scripted + [snapshots[-1]]

    def env_step_budgets(self) -> list[int] | None:
        """Each phase's budget in env steps; None when a phase ends after a number of episodes
        (its env steps are not known before it is played)."""
        budgets = [spec.env_steps for spec in self.league.phases]
        return None if None in budgets else [b for b in budgets if b is not None]

    def finished(self, phase: PhaseState) -> bool:
        spec = self.league.phases[phase.index]
        if spec.env_steps is not None:
            return phase.env_steps >= spec.env_steps
        assert spec.episodes is not None  # a phase has one budget (``ProtocolPhase._one_budget``)
        return phase.episodes >= spec.episodes


class SelfPlaySchedule:
    """Attacker and team learn in turn, each against the other side's whole pool."""

    def __init__(self, league: LeagueSettings):
        self.league = league
        self.phases = league.selfplay_phases + (league.exploiter_phases != "all")

    def side(self, index: int) -> Side:
        return "attacker" if index % 2 == 0 else "team"

    def trainee_kinds(self, index: int) -> tuple[str, ...]:
        """The kinds of player that train in a phase (learners, exploiters), the first the one
        whose games end it: with ``exploiter_phases: final`` or ``all_and_final``, the last
        phase is the exploiters' alone."""
        if index == self.league.selfplay_phases:  # (only with a final phase of exploiters)
            return ("exploiter",)
        return ("learner",) if self.league.exploiter_phases == "final" else ("learner", "exploiter")

    def opponents(self, index: int, scripted: list[Player], snapshots: list[Player]) -> list[Player]:
        return scripted + snapshots

    def budget(self, side: str) -> int:
        """Env steps after which a phase of ``side`` ends."""
        league = self.league
        team_budget = league.team_phase_env_steps
        return team_budget if side == "team" and team_budget is not None else league.phase_env_steps

    def env_step_budgets(self) -> list[int] | None:
        """Each phase's budget in env steps: the most it can take, as a phase that reaches its win rate ends sooner."""
        return [self.budget(self.side(index)) for index in range(self.phases)]

    def finished(self, phase: PhaseState) -> bool:
        league = self.league
        if phase.env_steps >= self.budget(phase.side):
            return True
        return phase.episodes >= league.min_phase_episodes and phase.learner_wins / phase.episodes >= league.snapshot_win_rate


Schedule = ProtocolSchedule | SelfPlaySchedule


def schedule_of(run: RunConfig) -> Schedule:
    return ProtocolSchedule(run.league) if run.league.mode == "protocol" else SelfPlaySchedule(run.league)
