"""A training run's lifecycle: start, begin, resume, finish, and what a stopped run says.

- ``new_run`` / ``start``: the run's config recorded, the league's first members (the
  learners, exploiters and scripted players of ``League.first_members``), the algorithm, and
  ``begin``: the untrained policies frozen as version 0 and checkpoint 0 committed. A new
  run that fails or is stopped before that removes what it wrote.
- ``resume_run`` / ``resume``: back to the newest intact checkpoint, the database rolled back
  to it and the checkpoint directories it does not record removed; the double-oracle best
  responses committed after that checkpoint was written added to its algorithm.
- ``finish``: the algorithm stopped, the whole frozen league evaluated on the fixed games
  (``evaluation.md``, the last file a run writes) unless that is already recorded.
- ``finished_iteration``, ``stopped_message``: whether a run has anything left to do, and
  the one line a stopped run ends with.

The training in between is ``Coordinator.train`` (``league.training.coordinator``);
``league.run`` parses the arguments, takes the run directory's lock and calls these.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import asdict
from pathlib import Path
from typing import Callable

import yaml

from league.config import RUN_CONFIG_FILE, RunConfig
from league.core.league import League
from league.core.match_plan import MatchPlan
from league.core.schedule import PhaseState
from league.rllib import bridge
from league.state.run_dir import LOCK_FILE, RunDirError, prune_checkpoints, record_config, usable_checkpoints
from league.state.store import DB_NAME, LeagueStore
from league.training import checkpoints, oracle
from league.training.coordinator import Coordinator, RunState
from league.training.progress import ProgressReporter
from league.training.stop import StopRequests


def phase_count(run: RunConfig) -> int:
    return League(run).schedule.phases


def phase_budgets(run: RunConfig) -> list[int] | None:
    """Each phase's env-step budget (``Schedule.env_step_budgets``), what the progress line's share and ETA count against."""
    return League(run).schedule.env_step_budgets()


# ------------------------------------------------------------ start
def start(run: RunConfig, run_dir: Path, store: LeagueStore, check: Callable[[], None] = lambda: None) -> Coordinator:
    """A new run in a new store: the league's first members, the algorithm, and checkpoint 0
    committed (``begin``). ``check`` runs before each commit (a stop request raises there)."""
    league = League(run)
    with store.transaction():
        record_config(store, run)
        for member in league.first_members():
            store.add_player(0, member)
    state = RunState(phase=PhaseState(index=0, side=league.schedule.side(0), start_iteration=0))
    first_attacker = store.players(side="attacker", kind="learner")[0]
    first_team = store.players(side="team", kind="scripted")[0]
    plan = MatchPlan([first_attacker.modules()], [[first_team.modules()]], [[1.0]], run.seed)
    algo = bridge.build_config(run, store.players(), plan).build_algo()
    check()
    coordinator = Coordinator(run, run_dir, store, algo, state, seed=run.seed, league=league)
    coordinator.oracle = oracle.carry_out
    begin(coordinator, check)
    return coordinator


def begin(coordinator: Coordinator, check: Callable[[], None] = lambda: None) -> None:
    """A new run's start: the untrained policies join the league as version 0 (the baseline
    every later snapshot is measured against), and checkpoint 0 is written and committed.
    ``check`` runs before the commit (a stop request raises there)."""
    store, state = coordinator.store, coordinator.state
    players = store.players()
    initial = [coordinator.snapshot(learner, players) for learner in store.players(kind="learner")]
    checkpoint = checkpoints.checkpoint(coordinator.algo, coordinator.run_dir, state.iteration)
    check()
    with store.transaction():
        for snapshot in initial:
            store.add_player(0, snapshot)
        state.rng = coordinator.rng.bit_generator.state
        store.record_checkpoint(0, str(checkpoint.relative_to(coordinator.run_dir)), json.dumps(asdict(state)))
    store.backup(checkpoint / DB_NAME)


def new_run(run: RunConfig, run_dir: Path, stop: StopRequests) -> Coordinator:
    """Create the run and commit its first checkpoint; on any failure or stop, remove what was written."""
    store = None
    try:
        (run_dir / RUN_CONFIG_FILE).write_text(yaml.safe_dump(run.model_dump(mode="json"), sort_keys=False))
        store = LeagueStore(run_dir, create=True)
        return start(run, run_dir, store, check=stop.check)
    except BaseException:
        if store is not None:
            store.close()
        for path in run_dir.iterdir():  # the lock file stays until the lock is released
            if path.name != LOCK_FILE:
                shutil.rmtree(path) if path.is_dir() else path.unlink()
        raise


# ------------------------------------------------------------ resume
def resume(run: RunConfig, run_dir: Path, store: LeagueStore, iteration: int, checkpoint: str) -> Coordinator:
    """Back to the intact ``checkpoint`` of ``iteration``: the database rolled back to it, the
    checkpoint directories it does not record (partial, damaged, later) removed."""
    store.rollback_after(iteration)
    prune_checkpoints(run_dir, store)
    last = store.last_checkpoint()
    assert last is not None  # ``iteration``'s, kept by the rollback
    algo = checkpoints.restore(run_dir / checkpoint)
    oracle.restore_modules(algo, run, run_dir, store.players())  # those that joined after the checkpoint was written
    coordinator = Coordinator(run, run_dir, store, algo, RunState.from_json(last[2]))
    coordinator.oracle = oracle.carry_out
    return coordinator


def intact_checkpoints(run_dir: Path, store: LeagueStore) -> tuple[list[tuple[int, str]], list[str]]:
    """``usable_checkpoints``, or a ``RunDirError`` when there is none to resume from."""
    usable, problems = usable_checkpoints(run_dir, store)
    if usable:
        return usable, problems
    if not problems:
        raise RunDirError(
            f"{run_dir} has no checkpoint: its first start was killed before it made one; "
            f"delete it (rm -r {run_dir}) and start the run again"
        )
    raise RunDirError(f"{run_dir} has no intact checkpoint to resume from ({'; '.join(problems)}): start a new run")


def resume_run(run_dir: Path, run: RunConfig, store: LeagueStore, say: Callable[[str], None]) -> Coordinator:
    """Restore the newest intact checkpoint; roll the database back to it."""
    usable, problems = intact_checkpoints(run_dir, store)
    iteration, path = usable[0]
    last_committed = (store.last_iteration() or {}).get("iteration", 0)
    coordinator = resume(run, run_dir, store, iteration, path)
    if problems:
        say(
            f"resuming from the checkpoint of iteration {iteration}, the newest intact one: {'; '.join(problems)}; "
            f"the league database was rolled back from iteration {last_committed} to {iteration}"
        )
    return coordinator


# ------------------------------------------------------------ end
def finish(coordinator: Coordinator, progress: ProgressReporter, stop: StopRequests) -> None:
    """The run's end: the algorithm stopped first (its env runners' CPUs go to the evaluation
    workers, which play saved modules), then the whole frozen league evaluated (unless the
    last iteration's evaluation is already recorded) and the evaluation workers stopped."""
    coordinator.algo.stop()
    state = coordinator.state
    if coordinator.store.get_meta("evaluated_iteration") != state.iteration:
        results, out, seconds = coordinator.evaluator.league(coordinator.store, state.iteration, stop)
        coordinator.time_split.final_evaluation += seconds
        progress.evaluation(results, state.env_steps)
        progress.message(f"evaluation of {len(results)} pairs written to {out}")
    coordinator.evaluator.close()


def finished_iteration(run_dir: Path, store: LeagueStore) -> int | None:
    """The last iteration of a run that trained to its end and was evaluated, its newest
    checkpoint intact, else None."""
    checkpoint = store.last_checkpoint()
    if checkpoint is None or not checkpoint[2].get("training_done") or usable_checkpoints(run_dir, store)[1]:
        return None
    return checkpoint[0] if store.get_meta("evaluated_iteration") == checkpoint[0] else None


def stopped_message(run_dir: Path, store: LeagueStore | None) -> str:
    if store is None:  # a new run stopped before its first checkpoint: nothing was kept
        return f"stopped before the first checkpoint; nothing was kept in {run_dir}"
    last = store.last_iteration()
    checkpoint = store.last_checkpoint()
    return (
        f"stopped at iteration {last['iteration'] if last else 0}, last checkpoint {checkpoint[0] if checkpoint else 'none'}, "
        f"resume with `python -m league.run --resume {run_dir}`"
    )
