"""The coordinator carries out the league's decisions, one training iteration at a time.

One iteration: ask the league (``league.core.league``) for this iteration's match plan,
``algo.train()``, read its result once (``TrainResult``), count what was played towards the
phase's end, evaluate when due, freeze the phase's trainees and move to the next phase when
the league says the phase is over, checkpoint when due, and commit the iteration
(``IterationRecord``) to the league database in one transaction.

Exploiters (``league.exploiters``) ride the same path: an exploiter is one more entry of the
phase's ``MatchPlan``, trained, snapshotted at the phase end and checkpointed like a learner
(the league decides whom it meets and that its games do not end the phase). With
``league.exploiters_restart`` each later phase starts it from its learner's version 0.

A graceful stop (``league.training.stop``) lets the current iteration finish and makes its
checkpoint due, so that a resume goes on from where the run stopped.

With ``league.double_oracle`` the iteration that ends a self-play phase is followed by PSRO's
step (``league.training.oracle``): a best response against the other side's Nash mixture joins the pool.

The run's lifecycle (start, resume, the final evaluation) is ``league.training.lifecycle``.
"""

from __future__ import annotations

import json
from contextlib import nullcontext
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np

from league.analysis.nash import meta_game, meta_game_players, missing_pairs, mixture_by_player
from league.analysis.regret_matching import restricted_distributions
from league.config import RunConfig
from league.core.league import League, OracleStep, Records
from league.core.payoff import aggregate, league_ratings
from league.core.players import NewPlayer, Player
from league.core.schedule import PhaseState
from league.core.seeding import Purpose, stream
from league.evaluation.engine import PairEvaluation
from league.evaluation.learning_curves import LearningCurves, Measurements
from league.rllib import bridge
from league.state.run_dir import prune_checkpoints
from league.state.store import DB_NAME, LeagueStore
from league.training import checkpoints
from league.training.evaluator import Evaluator
from league.training.progress import ProgressReporter, TimeSplit
from league.training.records import IterationRecord, IterationTiming, TrainResult, timed
from league.training.stop import StopRequests


@dataclass
class RunState:
    """Everything a resume needs besides the algorithm checkpoint and the database."""

    phase: PhaseState
    iteration: int = 0
    env_steps: int = 0
    episodes: int = 0
    learner_env_steps: dict[str, int] = field(default_factory=dict)  # by learner name
    training_done: bool = False
    rng: dict[str, Any] = field(default_factory=dict)

    @staticmethod
    def from_json(data: dict[str, Any]) -> "RunState":
        return RunState(**{**data, "phase": PhaseState(**data["phase"])})


class Coordinator:
    def __init__(self, run: RunConfig, run_dir: Path, store: LeagueStore, algo: Any, state: RunState,
                 seed: int | None = None, league: League | None = None):
        """``seed`` starts a new run's generator; a resumed run's ``state`` restores it."""
        self.run = run
        self.run_dir = run_dir
        self.store = store
        self.algo = algo
        self.state = state
        self.league = league or League(run)
        self.rng = np.random.default_rng(None if seed is None else stream(seed, Purpose.MATCH_PLANS))
        self.log: Callable[[str], None] = print  # the progress reporter's once training starts
        self.evaluator = Evaluator(run, run_dir, lambda text: self.log(text))
        self.runner_health = bridge.env_runner_health(algo)
        self.curves = LearningCurves(run, run_dir, lambda text: self.log(text))
        self.time_split = TimeSplit()  # this process's, for the run's last line
        # Carries out PSRO's step (``league.training.oracle.carry_out``); set by the lifecycle, since
        # the step trains a best response in a coordinator of its own (that module imports this one).
        self.oracle: Callable[[Coordinator, OracleStep, StopRequests | None], Any] | None = None
        if state.rng:
            self.rng.bit_generator.state = state.rng

    # ------------------------------------------------------------ whole run
    def train(self, progress: ProgressReporter, stop: StopRequests | None = None) -> None:
        """Train to the end; ``stop`` (SIGINT, SIGTERM) ends it after the iteration it arrives in, checkpointed."""
        self.log = progress.message
        if self.run.ppo.bf16:
            self.log("ppo.bf16: the learner's networks compute in bfloat16" if bridge.learner_computes_in_bf16(self.run)
                     else "ppo.bf16: this CPU has no native bfloat16 matmuls; the learner computes in float32")
        if self.run.ppo.compile_loss:
            self.log("ppo.compile_loss: the learner's loss is compiled at each trained module's first update"
                     if bridge.learner_compiles_loss(self.run)
                     else "ppo.compile_loss: torch finds no C++ compiler to build kernels with; the loss runs eagerly")
        self.set_trainable()
        self.add_due_oracles(stop)  # (a run resumed between a phase's end and its oracle)
        while not self.state.training_done:
            if stop:
                if stop.requested:
                    self.checkpoint_if_missing()  # a signal that came after the iteration's checkpoint decision
                stop.check()
            self.train_iteration(progress, stop)
            self.add_due_oracles(stop)

    def add_due_oracles(self, stop: StopRequests | None = None) -> None:
        """PSRO's step after each self-play phase (``league.double_oracle``; ``league.training.oracle``)."""
        while (step := self.league.oracle_due(self.state.phase, self.state.training_done, self.store.players())) is not None:
            if self.oracle is None:
                raise RuntimeError("league.double_oracle: a coordinator without its oracle step (the lifecycle's)")
            if stop:
                stop.check()
            self.oracle(self, step, stop)

    # ------------------------------------------------------------ iteration
    def train_iteration(self, progress: ProgressReporter, stop: StopRequests | None = None) -> None:
        """Train once against this iteration's opponents, count what was played, evaluate when
        due, end the phase when the league says so, checkpoint when due, commit, report."""
        played, meta_seconds = timed(self.meta_game_evaluations)
        records = self.records(played)
        players, st = records.players, self.state
        plan, weights = self.league.match_plan(st.phase, records, seed=int(self.rng.integers(2**31)))
        bridge.set_match_plan(self.algo, plan)
        bridge.begin_iteration(self.algo, self.run.seed, st.iteration + 1)
        with stop.interruptible(signals=2) if stop else nullcontext():  # a first signal waits for the iteration's end
            result, seconds = timed(self.algo.train)
        train = TrainResult.read(result, players, seconds, bridge.take_learning_seconds(self.algo))
        self.report_runner_health()

        phase = st.phase
        st.iteration += 1
        steps_before = dict(st.learner_env_steps)
        steps = self.count(train, players)
        (evaluation, curves), evaluation_seconds = timed(lambda: self.evaluate_iteration(played, players, steps_before))
        timing = IterationTiming(sampling=seconds - train.learning_seconds, learning=train.learning_seconds,
                                 evaluation=evaluation_seconds + meta_seconds)
        self.time_split.training += seconds
        self.time_split.evaluation += timing.evaluation
        trained_phase = replace(phase)  # this iteration's phase, before a phase change
        snapshots: list[NewPlayer] = []
        if self.league.phase_over(phase):
            snapshots = [self.snapshot(trainee, players) for trainee in self.league.phase_trainees(phase, players)]
            self.next_phase(players)
        stopping = stop is not None and stop.requested
        due = self.league.checkpoint_due(st.iteration, len(snapshots), st.training_done, stopping)
        record = IterationRecord(
            st.iteration, trained_phase, train, steps, st.env_steps, st.episodes, snapshots,
            [self.snapshot_name(s) for s in snapshots], evaluation, curves, weights, timing,
            league_size=len(players) + len(snapshots),
            checkpoint=checkpoints.checkpoint(self.algo, self.run_dir, st.iteration) if due else None,
        )
        self.commit(record)
        prune_checkpoints(self.run_dir, self.store)
        progress.iteration(record)

    def records(self, played: list[PairEvaluation]) -> Records:
        """The league's records as the store holds them (with ``played``, the meta-game's pairs evaluated now)."""
        players = self.store.players()
        strategy = self.meta_strategy(players, played) if self.run.league.pfsp == "nash" else None
        return Records(players, self.store.outcome_rows("training"), strategy)

    def meta_game_evaluations(self) -> list[PairEvaluation]:
        """PSRO's rule (``league.pfsp: nash``) needs every pair of frozen players evaluated: the
        pairs without an evaluation yet (a new snapshot's), played now, to be recorded with the iteration."""
        if self.run.league.pfsp != "nash":
            return []
        attackers, teams = meta_game_players(self.store.players())
        missing = missing_pairs(attackers, teams, aggregate(self.store.newest_evaluation_rows()))
        return self.evaluator.evaluate(missing) if missing else []

    def meta_strategy(self, players: list[Player], played: list[PairEvaluation]) -> dict[int, float] | None:
        """Each frozen player's weight in its side's meta-strategy (``league.double_oracle.meta_solver``) of the
        meta-game on each pair's newest evaluation, or None without one."""
        payoff = aggregate(self.store.newest_evaluation_rows())
        payoff.update({(r.attacker.id, r.team.id): (r.attacker_wins, r.games) for r in played})
        meta = meta_game(*meta_game_players(players), payoff)
        if meta is None:
            return None
        return restricted_distributions(meta) if self.run.league.double_oracle.meta_solver == "regret_matching" else (
            mixture_by_player(meta))

    def count(self, train: TrainResult, players: list[Player]) -> int:
        """Add this ``train()``'s episodes and env steps to the run's counts and the phase's progress; its env steps."""
        st = self.state
        st.episodes += sum(row.count for row in train.outcomes)
        steps = train.sampled_env_steps - st.env_steps
        st.env_steps = train.sampled_env_steps
        for name, played in train.trainee_steps.items():
            st.learner_env_steps[name] = st.learner_env_steps.get(name, 0) + played
        self.league.count_played(st.phase, players, train.outcomes, train.trainee_steps, steps)
        return steps

    def evaluate_iteration(self, played: list[PairEvaluation], players: list[Player],
                           steps_before: dict[str, int]) -> tuple[list[PairEvaluation], Measurements]:
        """The iteration's evaluations (``played``, and the learners when due) and learning-curve points."""
        st, phase, league = self.state, self.state.phase, self.league
        candidates = league.candidates(phase, players)
        evaluation = list(played)
        if league.evaluation_due(st.iteration):
            learners = league.in_phase(phase, players, "learner")
            evaluation += self.evaluator.learners_now(self.algo, phase.side, learners, candidates)
        curves = self.curves.measure(
            lambda learner: bridge.live_module(self.algo, self.run, learner), self.store,
            league.learners(phase.side, players), candidates, steps_before, st.learner_env_steps,
        )
        return evaluation, curves

    def snapshot(self, trainee: Player, players: list[Player]) -> NewPlayer:
        """Freeze a learner or an exploiter as a new league member (its module saved); not yet in the store."""
        steps = self.state.learner_env_steps.get(trainee.name, 0)
        return checkpoints.freeze(self.algo, self.run, self.run_dir, trainee, self.league.snapshot(trainee, players, steps))

    def snapshot_name(self, snapshot: NewPlayer) -> str:
        """How the progress line names a new snapshot."""
        return snapshot.name

    def next_phase(self, players: list[Player]) -> None:
        following = self.league.next_phase(self.state.phase, self.state.iteration)
        if following is None:
            self.state.training_done = True
            return
        self.state.phase = following
        if self.run.league.exploiters_restart:
            for exploiter in self.league.in_phase(following, players, "exploiter"):
                bridge.restart_module(self.algo, exploiter.name, self.league.untrained(exploiter, players).name)
        self.set_trainable()
        # A phase starts with new games: the old phase's learner plays no game of the new one
        # (its unfinished games trained it as truncated chunks, and are not counted as played).
        bridge.restart_games(self.algo)

    def set_trainable(self) -> None:
        """Train the current phase's players only."""
        trainees = self.league.phase_trainees(self.state.phase, self.store.players())
        bridge.set_trainable(self.algo, [trainee.name for trainee in trainees])

    def commit(self, record: IterationRecord) -> None:
        """The iteration's one transaction: results, new snapshots, steps, ratings, the
        iteration's row and, when one was written, its checkpoint with the run state."""
        st, store, iteration = self.state, self.store, record.iteration
        with store.transaction():
            store.record_outcomes(iteration, "training", record.train.outcomes)
            for snapshot in record.snapshots:
                store.add_player(iteration, snapshot)
            for trainee in self.league.trainees(store.players()):
                store.set_player_steps(trainee.id, st.learner_env_steps.get(trainee.name, 0))
            for r in record.evaluation:
                store.record_evaluation(iteration, r.outcome_rows())
            self.curves.record(store, iteration, record.curves)
            store.record_ratings(iteration, league_ratings(store.counted_results(), [p.id for p in store.players()]))
            store.record_iteration(
                iteration, phase=record.phase.index, learner_side=record.phase.side, env_steps=record.env_steps,
                episodes=record.episodes, steps_per_second=record.steps / record.train.seconds,
                wall_seconds=record.train.seconds, returns=json.dumps(record.train.returns),
            )
            st.rng = self.rng.bit_generator.state
            if record.checkpoint is not None:
                store.record_checkpoint(iteration, str(record.checkpoint.relative_to(self.run_dir)), json.dumps(asdict(st)))
        if record.checkpoint is not None:
            store.backup(record.checkpoint / DB_NAME)  # what `--resume` restores a damaged league.db from

    def checkpoint_if_missing(self) -> None:
        """Checkpoint the last committed iteration unless it already was: the run as ``commit`` would have saved it."""
        st, store = self.state, self.store
        last = store.last_checkpoint()
        if last is not None and last[0] == st.iteration:
            return
        path = checkpoints.checkpoint(self.algo, self.run_dir, st.iteration)
        with store.transaction():
            store.record_checkpoint(st.iteration, str(path.relative_to(self.run_dir)), json.dumps(asdict(st)))
        store.backup(path / DB_NAME)

    def report_runner_health(self) -> None:
        """Say when remote env runners are lost (a node died) or come back."""
        healthy, total, restarts = bridge.env_runner_health(self.algo)
        before = self.runner_health
        if healthy < before[0]:
            self.log(
                f"lost {before[0] - healthy} of {total} env runners in iteration {self.state.iteration + 1}: "
                f"their samples of this iteration are dropped; sampling goes on with {healthy} runner(s)"
            )
        if restarts > before[2] or healthy > before[0]:
            self.log(f"env runners back to {healthy} of {total} healthy ({restarts} restarts so far)")
        self.runner_health = (healthy, total, restarts)
