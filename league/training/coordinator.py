"""The training loop: phases, opponents, snapshots, checkpoints, all recorded in the store.

One iteration: pick the learner's opponents by PFSP (``MatchPlan``), ``algo.train()``,
record who played whom with which outcome, snapshot the learner when its phase ends,
checkpoint, and commit the iteration to the league database in one transaction.

Exploiters (``league.exploiters``) ride the same path: an exploiter is one more entry of
the phase's ``MatchPlan`` (so it gets as many of the phase's games as each learner),
whose only opponents are the other side's newest snapshots (``current_opponents``); it
is trained, snapshotted at the phase end and checkpointed like a learner. Its games do
not count towards the phase's end (``count_played``), and it never enters a pool but as
a frozen ``exploiter_snapshot``. It keeps its weights from phase to phase, or, with
``league.exploiters_restart``, starts each later phase from its learner's version 0.
With ``league.exploiter_phases: final`` the exploiters train only in one more phase after
the self-play phases, alone, from their untrained policies; that phase counts their games
(``trainee_kinds`` of the schedule).

Which side learns in a phase, against whom, and when the phase ends is the run's
schedule (``league.core.schedule``: the paper's protocol, or self-play).

The run's lifecycle is here too: ``Coordinator.start`` (the first league members and
checkpoint 0), ``Coordinator.resume`` (back to an intact checkpoint), ``train``, and
``finish`` (the whole frozen league on the fixed games, ``evaluation.md``).
"""

from __future__ import annotations

import json
import pickle
import time
from contextlib import nullcontext
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np

from league.rllib import bridge
from league.config import RunConfig
from league.analysis.nash import SUPPORT_THRESHOLD, meta_game, meta_game_players, missing_pairs
from league.evaluation.learning_curves import LearningCurves, Measurements
from league.evaluation.engine import EvaluationPool, PairEvaluation, evaluate_pairs
from league.evaluation.results import record_evaluations
from league.evaluation.tables import evaluation_markdown
from league.core.payoff import OutcomeCount, aggregate, league_ratings, record_against, win_rate
from league.core.match_plan import MatchPlan
from league.core.pfsp import with_scripted_share
from league.core.players import POOL_KINDS, SNAPSHOT_KIND, Player, other_side
from league.training.progress import IterationTiming, ProgressReporter, TimeSplit
from league.state.run_dir import (
    EVALUATION_FILE, fresh_directory, prune_checkpoints, record_config, write_checkpoint, write_replacing,
)
from league.core.schedule import PhaseState, schedule_of
from league.core.seeding import Purpose, stream
from league.training.stop import StopRequests
from league.state.store import DB_NAME, LeagueStore

GAMES_FILE = "games_in_flight.pkl"  # in a checkpoint directory: the env runners' games in flight


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


def phase_count(run: RunConfig) -> int:
    return schedule_of(run).phases


class Coordinator:
    def __init__(
        self, run: RunConfig, run_dir: Path, store: LeagueStore, algo: Any, state: RunState, seed: int | None = None
    ):
        """``seed`` starts a new run's generator; a resumed run's ``state`` restores it."""
        self.run = run
        self.run_dir = run_dir
        self.store = store
        self.algo = algo
        self.state = state
        self.schedule = schedule_of(run)
        self.rng = np.random.default_rng(None if seed is None else stream(seed, Purpose.MATCH_PLANS))
        self.evaluation_pool: EvaluationPool | None = None  # made at the first evaluation
        self.log: Callable[[str], None] = print  # the progress reporter's once training starts
        self.runner_health = bridge.env_runner_health(algo)
        self.curves = LearningCurves(run, run_dir, lambda text: self.log(text))
        self.time_split = TimeSplit()  # this process's, for the run's last line
        if state.rng:
            self.rng.bit_generator.state = state.rng

    @classmethod
    def start(cls, run: RunConfig, run_dir: Path, store: LeagueStore, check: Callable[[], None] = lambda: None) -> "Coordinator":
        """A new run in a new store: the league's first members (the learners and the scripted
        players), the algorithm, and checkpoint 0 committed (``begin``). ``check`` runs
        before each commit (a stop request raises there)."""
        learners = [("attacker", method) for method in run.attacker_methods] + [("team", None)]
        with store.transaction():
            record_config(store, run)
            for side, method in learners:
                store.add_player(0, side=side, kind="learner", version=0, reward_method=method)
            for side, method in learners:  # each learner of a side with exploiters gets its twin
                if side in run.league.exploiters:
                    store.add_player(0, side=side, kind="exploiter", version=0, reward_method=method)
            for name in run.league.scripted_attackers:
                store.add_player(0, side="attacker", kind="scripted", version=0, scripted_attacker=name)
            for team in run.league.scripted_teams:
                store.add_player(
                    0, side="team", kind="scripted", version=0, scripted_targeter=team.targeter, scripted_defender=team.defender
                )
        state = RunState(phase=PhaseState(index=0, side=schedule_of(run).side(0), start_iteration=0))
        first_attacker = store.players(side="attacker", kind="learner")[0]
        first_team = store.players(side="team", kind="scripted")[0]
        plan = MatchPlan([first_attacker.modules()], [[first_team.modules()]], [[1.0]], run.seed)
        algo = bridge.build_config(run, store.players(), plan).build_algo()
        check()
        coordinator = cls(run, run_dir, store, algo, state, seed=run.seed)
        coordinator.begin(check)
        return coordinator

    @classmethod
    def resume(cls, run: RunConfig, run_dir: Path, store: LeagueStore, iteration: int, checkpoint: str) -> "Coordinator":
        """Back to the intact ``checkpoint`` of ``iteration``: the database rolled back to it, the
        checkpoint directories it does not record (partial, damaged, later) removed."""
        store.rollback_after(iteration)
        prune_checkpoints(run_dir, store)
        _, _, state_json = store.last_checkpoint()
        algo = bridge.restore_algorithm(run_dir / checkpoint)
        games = run_dir / checkpoint / GAMES_FILE
        if games.exists():  # (a checkpoint written before games in flight were kept has none: they start anew)
            bridge.restore_games(algo, pickle.loads(games.read_bytes()))
        return cls(run, run_dir, store, algo, RunState.from_json(state_json))

    # ------------------------------------------------------------ league views
    def learners(self, side: str) -> list[Player]:
        return self.store.players(side=side, kind="learner")

    def in_phase(self, kind: str) -> list[Player]:
        """The players of ``kind`` (learner, exploiter) that train in the current phase."""
        phase = self.state.phase
        return self.store.players(side=phase.side, kind=kind) if kind in self.schedule.trainee_kinds(phase.index) else []

    def phase_trainees(self) -> list[Player]:
        """Every player that trains in the current phase: its learners, then its exploiters."""
        return [p for kind in self.schedule.trainee_kinds(self.state.phase.index) for p in self.in_phase(kind)]

    def trainees(self) -> list[Player]:
        """Every player whose module trains (learners and exploiters), of both sides, in any phase."""
        return [p for p in self.store.players() if p.trains]

    def module_players(self) -> tuple[dict[str, Player], dict[tuple[str, str], Player]]:
        """Players by attacker module, and team players by (targeter, defender) module."""
        attackers, teams = {}, {}
        for player in self.store.players():
            modules = player.modules()
            if player.side == "attacker":
                attackers[modules["attacker"]] = player
            else:
                teams[(modules["targeter"], modules["defender"])] = player
        return attackers, teams

    def candidates(self, side: str) -> list[Player]:
        """The opponents of the ``side`` learner in the current phase."""
        pool_side = other_side(side)
        return self.schedule.opponents(
            self.state.phase.index,
            self.store.players(side=pool_side, kind="scripted"),
            [p for p in self.store.players(side=pool_side) if p.kind in POOL_KINDS],  # oldest first
        )

    def current_opponents(self, side: str) -> list[Player]:
        """The other side's learners as they are now, the only opponents of the ``side`` exploiters:
        each one's newest snapshot. The other side does not train in this phase, and its newest
        snapshot was taken when it last stopped (version 0, its untrained policy, before its first phase)."""
        newest: dict[int, Player] = {}
        for snapshot in self.store.players(side=other_side(side), kind="snapshot"):  # oldest first
            newest[snapshot.parent] = snapshot  # by lineage: the learner it was frozen from
        return list(newest.values())

    def untrained(self, exploiter: Player) -> Player:
        """The version 0 of the learner an exploiter is the twin of (same side, same reward method)."""
        [untrained] = [p for p in self.store.players(side=exploiter.side, kind="snapshot")
                       if p.version == 0 and p.reward_method == exploiter.reward_method]
        return untrained

    def learner_win_rates(self, learner: Player, opponents: list[Player]) -> list[float]:
        table = aggregate(self.store.outcome_rows("training"))
        return [win_rate(*record_against(table, learner.side, learner.id, opponent.id)) for opponent in opponents]

    def meta_game_evaluations(self) -> list[PairEvaluation]:
        """PSRO's rule (``league.pfsp: nash``) needs every pair of frozen players evaluated: the
        pairs without an evaluation yet (a new snapshot's), played now, to be recorded with the iteration."""
        attackers, teams = meta_game_players(self.store.players())
        missing = missing_pairs(attackers, teams, aggregate(self.store.newest_evaluation_rows()))
        return self.evaluate(missing) if missing else []

    def nash_weights(self, side: str, opponents: list[Player], played: list[PairEvaluation]) -> list[float]:
        """Each opponent's weight in its side's Nash mixture of the meta-game of every frozen
        player, on each pair's newest evaluation (``played``: evaluated this iteration)."""
        attackers, teams = meta_game_players(self.store.players())
        payoff = aggregate(self.store.newest_evaluation_rows())
        payoff.update({(r.attacker.id, r.team.id): (r.attacker_wins, r.games) for r in played})
        meta = meta_game(attackers, teams, payoff)
        if meta is None:
            raise RuntimeError("league.pfsp: nash needs every pair of frozen players evaluated (meta_game_evaluations)")
        players, mixture = (meta.teams, meta.equilibrium.column_mixture) if side == "attacker" else (
            meta.attackers, meta.equilibrium.row_mixture)
        by_id = {p.id: float(w) if w > SUPPORT_THRESHOLD else 0.0 for p, w in zip(players, mixture)}
        return [by_id.get(o.id, 0.0) for o in opponents]

    def match_plan(self, played: list[PairEvaluation] = ()) -> tuple[MatchPlan, dict[str, dict[str, float]]]:
        """This iteration's plan, and each learner's PFSP probability per opponent name
        (``played``: the meta-game's pairs evaluated for this iteration, ``meta_game_evaluations``).

        The side's exploiters join the plan as further entries with the other side's current
        learners as their only, equally likely, opponents."""
        side = self.state.phase.side
        learners = self.in_phase("learner")
        opponents = self.candidates(side)
        scripted = [o.kind == "scripted" for o in opponents]
        league = self.run.league
        share = league.scripted_share.get(side, 0.0)
        nash = self.nash_weights(side, opponents, list(played)) if league.pfsp == "nash" else None
        probabilities = [
            with_scripted_share(self.learner_win_rates(learner, opponents), scripted, share, league.pfsp, nash,
                                league.scripted_weighting)
            for learner in learners
        ]
        exploiters = self.in_phase("exploiter")
        targets = self.current_opponents(side) if exploiters else []
        plan = MatchPlan(
            learners=[player.modules() for player in learners + exploiters],
            opponents=[[o.modules() for o in opponents]] * len(learners) + [[t.modules() for t in targets]] * len(exploiters),
            probabilities=[p.tolist() for p in probabilities] + [[1.0] * len(targets)] * len(exploiters),
            seed=int(self.rng.integers(2**31)),
        )
        weights = {
            learner.name: {o.name: float(w) for o, w in zip(opponents, p)} for learner, p in zip(learners, probabilities)
        }
        return plan, weights

    # ------------------------------------------------------------ iteration
    def train_iteration(self, progress: ProgressReporter, stop: StopRequests | None = None) -> None:
        """Train once against this iteration's opponents, count what was played, evaluate when
        due, end the phase when the schedule says so, checkpoint when due, commit, report."""
        started = time.perf_counter()
        played = self.meta_game_evaluations() if self.run.league.pfsp == "nash" else []
        meta_seconds = time.perf_counter() - started
        plan, weights = self.match_plan(played)
        bridge.set_match_plan(self.algo, plan)
        bridge.begin_iteration(self.algo, self.run.seed, self.state.iteration + 1)
        started = time.perf_counter()
        with stop.interruptible() if stop else nullcontext():
            result = self.algo.train()
        seconds = time.perf_counter() - started
        learning = bridge.take_learning_seconds(self.algo)
        self.report_runner_health()

        st, phase = self.state, self.state.phase
        st.iteration += 1
        steps_before = dict(st.learner_env_steps)
        rows, steps = self.count_played(result)
        learners = self.learners(phase.side)
        every = self.run.evaluation.every_iterations
        started = time.perf_counter()
        evaluation = played + (self.evaluate_learners() if every and st.iteration % every == 0 else [])
        curves = self.curves.measure(
            lambda learner: bridge.live_module(self.algo, self.run, learner), self.store, learners, self.candidates(phase.side), steps_before, st.learner_env_steps
        )
        timing = IterationTiming(sampling=seconds - learning, learning=learning,
                                 evaluation=time.perf_counter() - started + meta_seconds)
        self.time_split.training += seconds
        self.time_split.evaluation += timing.evaluation
        trained_phase = replace(phase)  # this iteration's phase, before a phase change
        snapshots = []
        if self.schedule.finished(phase):
            snapshots = [self.snapshot(trainee) for trainee in self.phase_trainees()]
            self.next_phase()
        due = snapshots or st.training_done or st.iteration % self.run.checkpoint_every == 0
        checkpoint = self.checkpoint() if due else None
        self.commit(result, trained_phase, rows, snapshots, evaluation, curves, checkpoint, steps, seconds)
        self.prune_checkpoints()
        learner_names = [p.name for p in self.trainees()]
        progress.iteration(
            st.iteration, st.env_steps, len(self.store.players()), bridge.learner_stats(result, learner_names), weights,
            trained_phase, steps, timing, [self.store_name(c) for c in snapshots], evaluation,
        )

    def count_played(self, result: dict[str, Any]) -> tuple[list[OutcomeCount], int]:
        """Add this ``train()``'s episodes, wins and env steps to the run's and the phase's
        counts; returns its outcome rows and env steps.

        An exploiter's games and env steps are not the phase's progress: the phase counts its
        learners' wins and episodes, and every env step but the exploiters' (a phase starts
        with new games: none of the previous phase's side is finished in it). In a phase of
        exploiters alone (``league.exploiter_phases: final``) it counts theirs."""
        st, phase = self.state, self.state.phase
        rows = self.outcome_rows(result)
        counted = self.schedule.trainee_kinds(phase.index)[0]
        counted_ids = {p.id for p in self.in_phase(counted)}
        for row in rows:
            st.episodes += row.count
            if counted_ids & {row.attacker, row.team}:
                phase.episodes += row.count
                phase.learner_wins += row.wins(phase.side)
        total_steps = bridge.sampled_env_steps(result)
        steps = total_steps - st.env_steps
        st.env_steps = total_steps
        trainees = self.trainees()
        trainee_steps = bridge.learner_env_steps(result, trainees)
        for name, played in trainee_steps.items():
            st.learner_env_steps[name] = st.learner_env_steps.get(name, 0) + played
        phase.env_steps += steps - sum(trainee_steps[p.name] for p in trainees if p.kind != counted)
        return rows, steps

    def commit(self, result: dict[str, Any], phase: PhaseState, rows: list[OutcomeCount],
               snapshots: list[dict[str, Any]], evaluation: list[PairEvaluation], curves: Measurements, checkpoint: Path | None,
               steps: int, seconds: float) -> None:
        """The iteration's one transaction: results, new snapshots, steps, ratings, the
        iteration's row (of ``phase``, the one it trained in) and, when one was written, its
        checkpoint with the run state."""
        st = self.state
        with self.store.transaction():
            self.store.record_outcomes(st.iteration, "training", rows)
            for columns in snapshots:
                self.store.add_player(st.iteration, **columns)
            for trainee in self.trainees():
                self.store.set_player_steps(trainee.id, st.learner_env_steps.get(trainee.name, 0))
            for r in evaluation:
                self.store.record_evaluation(st.iteration, r.outcome_rows())
            self.curves.record(self.store, st.iteration, curves)
            self.store.record_ratings(st.iteration, league_ratings(self.store.counted_results(), [p.id for p in self.store.players()]))
            self.store.record_iteration(
                st.iteration,
                phase=phase.index,
                learner_side=phase.side,
                env_steps=st.env_steps,
                episodes=st.episodes,
                steps_per_second=steps / seconds,
                wall_seconds=seconds,
                returns=json.dumps(bridge.module_returns(result, [p.name for p in self.trainees()])),
            )
            st.rng = self.rng.bit_generator.state
            if checkpoint is not None:
                self.store.record_checkpoint(st.iteration, str(checkpoint.relative_to(self.run_dir)), json.dumps(asdict(st)))
        if checkpoint is not None:
            self.store.backup(checkpoint / DB_NAME)  # what `--resume` restores a damaged league.db from

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

    def outcome_rows(self, result: dict[str, Any]) -> list[OutcomeCount]:
        """The outcomes of the episodes that ended in this iteration, by player."""
        attackers, teams = self.module_players()
        rows = []
        for (attacker_module, targeter_module, defender_module), outcome, count in bridge.episode_outcomes(result):
            attacker = attackers[attacker_module]
            team = teams[(targeter_module, defender_module)]
            rows.append(OutcomeCount(attacker.id, team.id, outcome, count))
        return rows

    def next_phase(self) -> None:
        index = self.state.phase.index + 1
        if index >= self.schedule.phases:
            self.state.training_done = True
            return
        side = self.schedule.side(index)
        self.state.phase = PhaseState(index=index, side=side, start_iteration=self.state.iteration)
        if self.run.league.exploiters_restart:
            for exploiter in self.in_phase("exploiter"):
                bridge.restart_module(self.algo, exploiter.name, self.untrained(exploiter).name)
        self.set_trainable()
        # A phase starts with new games: the old phase's learner plays no game of the new one
        # (its unfinished games trained it as truncated chunks, and are not counted as played).
        bridge.restart_games(self.algo)

    def set_trainable(self) -> None:
        """Train the current phase's players only."""
        bridge.set_trainable(self.algo, [trainee.name for trainee in self.phase_trainees()])

    def evaluate_learners(self) -> list[PairEvaluation]:
        """The phase's learners, as they are now, against their opponents on the fixed games."""
        side = self.state.phase.side
        pairs = []
        for learner in self.in_phase("learner"):
            path = fresh_directory(self.run_dir / "players" / learner.name)
            bridge.save_module(self.algo, learner.name, path)
            current = replace(learner, checkpoint=str(path.relative_to(self.run_dir)))
            for opponent in self.candidates(side):
                pairs.append((current, opponent) if side == "attacker" else (opponent, current))
        return self.evaluate(pairs)

    def evaluate(self, pairs: list[tuple[Player, Player]]) -> list[PairEvaluation]:
        """``(attacker, team)`` pairs on the fixed games, by the evaluation workers (started at the first call)."""
        ev = self.run.evaluation
        if self.evaluation_pool is None and ev.workers > 0:
            self.evaluation_pool = EvaluationPool(
                self.run.game, self.run_dir, ev.workers, ev.cpus_per_worker, ev.custom_resources_per_worker, self.log,
                torch_threads=self.run.resources.torch_threads,
            )
        return evaluate_pairs(self.run.game, self.run_dir, pairs, ev.episodes, pool=self.evaluation_pool)

    def begin(self, check: Callable[[], None] = lambda: None) -> None:
        """A new run's start: the untrained policies join the league as version 0 (the baseline
        every later snapshot is measured against), and checkpoint 0 is written and committed.
        ``check`` runs before the commit (a stop request raises there)."""
        initial = [self.snapshot(learner) for learner in self.store.players(kind="learner")]
        checkpoint = self.checkpoint()
        check()
        with self.store.transaction():
            for columns in initial:
                self.store.add_player(0, **columns)
            self.state.rng = self.rng.bit_generator.state
            self.store.record_checkpoint(0, str(checkpoint.relative_to(self.run_dir)), json.dumps(asdict(self.state)))
        self.store.backup(checkpoint / DB_NAME)

    # ------------------------------------------------------------ snapshots, checkpoints
    @staticmethod
    def store_name(columns: dict[str, Any]) -> str:
        return Player(id=-1, **columns).name

    def snapshot(self, trainee: Player) -> dict[str, Any]:
        """Freeze a learner or an exploiter as a new league member; returns its player columns.

        A learner's versions start at 0 (its untrained policy, frozen by ``begin``); an
        exploiter's at 1, after its first phase: its untrained policy never joins the pool."""
        side, kind = trainee.side, SNAPSHOT_KIND[trainee.kind]
        versions = [p.version for p in self.store.players(side=side, kind=kind) if p.reward_method == trainee.reward_method]
        version = 1 + max(versions, default=-1 if kind == "snapshot" else 0)
        player = Player(id=-1, side=side, kind=kind, version=version, reward_method=trainee.reward_method)
        bridge.add_snapshot(self.algo, self.run, player, trainee.name)
        # (one left over by a run killed before it committed this snapshot is replaced)
        path = fresh_directory(self.run_dir / "players" / player.name)
        bridge.save_module(self.algo, player.name, path)
        return {
            "side": side,
            "kind": kind,
            "version": version,
            "reward_method": trainee.reward_method,
            "parent": trainee.id,
            "env_steps": self.state.learner_env_steps.get(trainee.name, 0),
            "checkpoint": str(path.relative_to(self.run_dir)),
        }

    def checkpoint(self) -> Path:
        """The algorithm and the env runners' games in flight, in this iteration's checkpoint directory."""

        def save(directory: Path) -> None:
            self.algo.save_to_path(str(directory))
            (directory / GAMES_FILE).write_bytes(pickle.dumps(bridge.games_in_flight(self.algo)))

        return write_checkpoint(self.run_dir, self.state.iteration, save)

    def prune_checkpoints(self) -> None:
        prune_checkpoints(self.run_dir, self.store)

    # ------------------------------------------------------------ whole run
    def train(self, progress: ProgressReporter, stop: StopRequests | None = None) -> None:
        """Train to the end; ``stop`` (SIGINT, SIGTERM) ends it between iterations or during sampling and learning."""
        self.log = progress.message
        if self.run.ppo.bf16:
            self.log("ppo.bf16: the learner's networks compute in bfloat16" if bridge.learner_computes_in_bf16(self.run)
                     else "ppo.bf16: this CPU has no native bfloat16 matmuls; the learner computes in float32")
        self.set_trainable()
        while not self.state.training_done:
            if stop:
                stop.check()
            self.train_iteration(progress, stop)

    def finish(self, progress: ProgressReporter, stop: StopRequests) -> None:
        """The run's end: the algorithm stopped first (its env runners' CPUs go to the evaluation
        workers, which play saved modules), then the whole frozen league evaluated (unless the
        last iteration's evaluation is already recorded) and the evaluation workers stopped."""
        self.algo.stop()
        if self.store.get_meta("evaluated_iteration") != self.state.iteration:
            self.evaluate_league(progress, stop)
        if self.evaluation_pool is not None:
            self.evaluation_pool.close()

    def evaluate_league(self, progress: ProgressReporter, stop: StopRequests) -> Path:
        """Every frozen attacker against every frozen team on the fixed evaluation games:
        recorded with refitted ratings, written to ``evaluation.md``."""
        store, run = self.store, self.run
        frozen = [p for p in store.players() if not p.trains]
        attackers = [p for p in frozen if p.side == "attacker"]
        teams = [p for p in frozen if p.side == "team"]
        pairs = [(attacker, team) for attacker in attackers for team in teams]
        ev = run.evaluation
        started = time.perf_counter()
        with stop.interruptible():  # playing the games writes nothing
            results = evaluate_pairs(
                run.game, self.run_dir, pairs, ev.episodes, ev.workers, ev.cpus_per_worker,
                self.evaluation_pool, ev.custom_resources_per_worker, run.resources.torch_threads,
            )
        self.time_split.final_evaluation += time.perf_counter() - started
        iteration = self.state.iteration
        with store.transaction():
            record_evaluations(store, iteration, results)
            store.set_meta("evaluated_iteration", iteration)
        out = self.run_dir / EVALUATION_FILE
        write_replacing(out, evaluation_markdown(run, iteration, results))
        progress.evaluation(results, self.state.env_steps)
        progress.message(f"evaluation of {len(results)} pairs written to {out}")
        return out

