"""The league: what it decides, from its records. It reads no store and plays no game.

| question                                       | answer                                           |
| ---------------------------------------------- | ------------------------------------------------ |
| who joins a new league                          | ``first_members``: learners, exploiters, scripted |
| who trains in a phase                           | ``phase_trainees`` (the schedule's kinds)         |
| whom a learner meets, with which probability    | ``candidates``, ``match_plan`` (PFSP on its training results, or the Nash mixture) |
| whom an exploiter meets                         | ``current_opponents``: the other side's newest snapshots |
| how far a phase has come                        | ``count_played``                                  |
| when a phase ends, and so a snapshot is taken  | ``phase_over``, then ``snapshot`` of each trainee and ``next_phase`` |
| when the learners are evaluated, when a checkpoint is written | ``evaluation_due``, ``checkpoint_due`` |
| when PSRO's best response is due, of which side, for how long | ``oracle_due`` (``league.double_oracle``) |

Which side learns, against whom and for how long is the run's schedule
(``league.core.schedule``). The coordinator (``league.training.coordinator``) hands the
league its records (``Records``: the players and the training results, as the store holds
them) and carries out what it answers: it trains, saves, evaluates and records.
"""

from __future__ import annotations

from dataclasses import dataclass

from league.config import RunConfig
from league.core.match_plan import MatchPlan
from league.core.payoff import OutcomeCount, aggregate, record_against, win_rate
from league.core.pfsp import with_scripted_share
from league.core.players import NewPlayer, Player, Side, other_side, role_of
from league.core.schedule import PhaseState, Schedule, schedule_of
from league.core.seeding import Purpose, run_seed


@dataclass(frozen=True)
class Records:
    """What the league decides from: its members, oldest first, and the outcomes of training games."""

    players: list[Player]
    training: list[OutcomeCount]
    # PSRO's rule (``league.pfsp: nash``): each frozen player's weight in its side's meta-strategy, the Nash
    # mixture of the meta-game (or regret matching's, ``league.double_oracle.meta_solver``)
    meta_strategy: dict[int, float] | None = None


Weights = dict[str, dict[str, float]]  # a learner's probability per opponent, by name


@dataclass(frozen=True)
class OracleStep:
    """PSRO's step owed by self-play phase ``phase`` (``league.double_oracle``): a best response of
    the phase's side, trained against the other side's meta-strategy and frozen into the pool as
    ``member`` (kind ``oracle``, no module yet; its training seed and budget in its columns)."""

    phase: int
    member: NewPlayer

    @property
    def seed(self) -> int:
        assert self.member.seed is not None
        return self.member.seed

    @property
    def env_steps(self) -> int:
        assert self.member.env_step_budget is not None
        return self.member.env_step_budget

    @property
    def exploited_side(self) -> Side:
        return "team" if self.member.side == "attacker" else "attacker"


class League:
    def __init__(self, run: RunConfig):
        self.run = run
        self.settings = run.league
        self.schedule: Schedule = schedule_of(run)

    # ------------------------------------------------------------ members
    def first_members(self) -> list[NewPlayer]:
        """A new league's members: the learners, each learner's exploiter twin on the sides with
        exploiters, then the scripted players."""
        learners: list[tuple[Side, int | None]] = [("attacker", method) for method in self.run.attacker_methods]
        learners.append(("team", None))
        members = [NewPlayer(side, "learner", 0, method) for side, method in learners]
        members += [NewPlayer(side, "exploiter", 0, method) for side, method in learners if side in self.settings.exploiters]
        members += [NewPlayer("attacker", "scripted", 0, scripted_attacker=name) for name in self.settings.scripted_attackers]
        members += [NewPlayer("team", "scripted", 0, scripted_targeter=team.targeter, scripted_defender=team.defender)
                    for team in self.settings.scripted_teams]
        return members

    @staticmethod
    def learners(side: str, players: list[Player]) -> list[Player]:
        return [p for p in players if p.side == side and p.kind == "learner"]

    @staticmethod
    def trainees(players: list[Player]) -> list[Player]:
        """Every player whose module trains (learners and exploiters), of both sides, in any phase."""
        return [p for p in players if p.trains]

    def in_phase(self, phase: PhaseState, players: list[Player], kind: str) -> list[Player]:
        """The players of ``kind`` (learner, exploiter) that train in ``phase``."""
        if kind not in self.schedule.trainee_kinds(phase.index):
            return []
        return [p for p in players if p.side == phase.side and p.kind == kind]

    def phase_trainees(self, phase: PhaseState, players: list[Player]) -> list[Player]:
        """Every player that trains in ``phase``: its learners, then its exploiters."""
        return [p for kind in self.schedule.trainee_kinds(phase.index) for p in self.in_phase(phase, players, kind)]

    # ------------------------------------------------------------ opponents
    def candidates(self, phase: PhaseState, players: list[Player]) -> list[Player]:
        """The opponents of the phase's learners."""
        pool_side = other_side(phase.side)
        return self.schedule.opponents(
            phase.index,
            [p for p in players if p.side == pool_side and p.kind == "scripted"],
            [p for p in players if p.side == pool_side and p.in_pool],  # oldest first
        )

    @staticmethod
    def current_opponents(side: str, players: list[Player]) -> list[Player]:
        """The other side's learners as they are now, the only opponents of the ``side`` exploiters:
        each one's newest snapshot. The other side does not train in this phase, and its newest
        snapshot was taken when it last stopped (version 0, its untrained policy, before its first phase)."""
        newest: dict[int | None, Player] = {}
        for snapshot in players:  # oldest first
            if snapshot.side == other_side(side) and snapshot.kind == "snapshot":
                newest[snapshot.parent] = snapshot  # by lineage: the learner it was frozen from
        return list(newest.values())

    @staticmethod
    def untrained(exploiter: Player, players: list[Player]) -> Player:
        """The version 0 of the learner an exploiter is the twin of (same side, same reward method)."""
        [untrained] = [p for p in players if p.side == exploiter.side and p.kind == "snapshot"
                       and p.version == 0 and p.reward_method == exploiter.reward_method]
        return untrained

    def match_plan(self, phase: PhaseState, records: Records, seed: int) -> tuple[MatchPlan, Weights]:
        """The phase's plan for one iteration (episodes drawn from ``seed``), and each learner's
        probability per opponent.

        A learner meets the phase's candidates by PFSP on its training results (with the
        config's share for the scripted players), or by their meta-strategy weights (``records.meta_strategy``);
        the side's exploiters join the plan as further entries with the other side's current
        learners as their only, equally likely, opponents."""
        players, settings = records.players, self.settings
        learners = self.in_phase(phase, players, "learner")
        opponents = self.candidates(phase, players)
        scripted = [o.is_scripted for o in opponents]
        share = settings.scripted_share.get(phase.side, 0.0)
        nash = self._meta_strategy_weights(opponents, records) if settings.pfsp == "nash" else None
        table = aggregate(records.training)
        probabilities = [
            with_scripted_share([win_rate(*record_against(table, learner.side, learner.id, o.id)) for o in opponents],
                                scripted, share, settings.pfsp, nash, settings.scripted_weighting)
            for learner in learners
        ]
        exploiters = self.in_phase(phase, players, "exploiter")
        targets = self.current_opponents(phase.side, players) if exploiters else []
        plan = MatchPlan(
            learners=[player.modules() for player in learners + exploiters],
            opponents=[[o.modules() for o in opponents]] * len(learners) + [[t.modules() for t in targets]] * len(exploiters),
            probabilities=[p.tolist() for p in probabilities] + [[1.0] * len(targets)] * len(exploiters),
            seed=seed,
        )
        weights = {
            learner.name: {o.name: float(w) for o, w in zip(opponents, p)} for learner, p in zip(learners, probabilities)
        }
        return plan, weights

    @staticmethod
    def _meta_strategy_weights(opponents: list[Player], records: Records) -> list[float]:
        if records.meta_strategy is None:
            raise RuntimeError("league.pfsp: nash needs every pair of frozen players evaluated (the meta-game's mixtures)")
        return [records.meta_strategy.get(o.id, 0.0) for o in opponents]

    # ------------------------------------------------------------ phases, snapshots, checkpoints
    def count_played(
        self, phase: PhaseState, players: list[Player], outcomes: list[OutcomeCount], trainee_steps: dict[str, int], steps: int
    ) -> None:
        """Add an iteration's games (``outcomes``) and ``steps`` env steps to ``phase``'s progress.

        An exploiter's games and env steps are not the phase's progress: the phase counts its
        learners' wins and episodes, and every env step but the exploiters' (``trainee_steps``:
        each trainee's). In a phase of exploiters alone (``league.exploiter_phases: final``) it
        counts theirs."""
        counted = self.schedule.trainee_kinds(phase.index)[0]
        counted_ids = {p.id for p in self.in_phase(phase, players, counted)}
        for row in outcomes:
            if counted_ids & {row.attacker, row.team}:
                phase.episodes += row.count
                phase.learner_wins += row.wins(phase.side)
        phase.env_steps += steps - sum(trainee_steps[p.name] for p in self.trainees(players) if p.kind != counted)

    def phase_over(self, phase: PhaseState) -> bool:
        """Whether ``phase`` has ended: its trainees are then frozen (``snapshot``)."""
        return self.schedule.finished(phase)

    def next_phase(self, phase: PhaseState, iteration: int) -> PhaseState | None:
        """The phase after ``phase``, starting after ``iteration``; None when it was the last."""
        index = phase.index + 1
        if index >= self.schedule.phases:
            return None
        return PhaseState(index=index, side=self.schedule.side(index), start_iteration=iteration)

    @staticmethod
    def snapshot(trainee: Player, players: list[Player], env_steps: int) -> NewPlayer:
        """The frozen copy of a trainee, as a new member (its module not saved yet: no ``checkpoint``).

        A learner's versions start at 0 (its untrained policy, frozen when the run begins); an
        exploiter's at 1, after its first phase: its untrained policy never joins the pool."""
        role = role_of(trainee.kind)
        if role.frozen_as is None:
            raise ValueError(f"{trainee.name} does not train: it has no snapshots")
        versions = [p.version for p in players
                    if p.side == trainee.side and p.kind == role.frozen_as and p.reward_method == trainee.reward_method]
        version = 1 + max(versions, default=role.first_snapshot - 1)
        return NewPlayer(trainee.side, role.frozen_as, version, trainee.reward_method, parent=trainee.id, env_steps=env_steps)

    # ------------------------------------------------------------ PSRO's step
    def oracle_due(self, phase: PhaseState, training_done: bool, players: list[Player]) -> OracleStep | None:
        """The oldest finished self-play phase's best response not in the league yet, or None (also
        without ``league.double_oracle``). A phase is finished once the next one has started, the
        last one when training is done; a best response is matched to its phase by side and version
        (the ``k``-th phase of a side owes ``oracle`` version ``k``)."""
        env_steps = self.settings.double_oracle.env_steps
        if not env_steps:
            return None
        finished = min(phase.index + int(training_done), self.settings.selfplay_phases)
        joined = {(p.side, p.version) for p in players if p.kind == "oracle"}
        for index in range(finished):
            side = self.schedule.side(index)
            version = sum(self.schedule.side(i) == side for i in range(index + 1))
            if (side, version) not in joined:
                method = self.run.game.attacker_reward if side == "attacker" else None  # the one attacker a best response trains
                seed = run_seed(self.run.seed, Purpose.ORACLES, index)
                return OracleStep(index, NewPlayer(side, "oracle", version, method, seed=seed, env_step_budget=env_steps,
                                                   from_prior=True))
        return None

    def evaluation_due(self, iteration: int) -> bool:
        """Whether the phase's learners are evaluated against their opponents after ``iteration``."""
        every = self.run.evaluation.every_iterations
        return bool(every) and iteration % every == 0

    def checkpoint_due(self, iteration: int, snapshots: int, training_done: bool, stopping: bool = False) -> bool:
        """Whether ``iteration`` ends with a checkpoint: every ``checkpoint_every`` iterations, when it
        took snapshots, when training is done, and when the run is asked to stop."""
        return bool(snapshots) or training_done or stopping or iteration % self.run.checkpoint_every == 0
