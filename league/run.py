"""Train a league: ``python -m league.run --config attacker_method2.yaml``.

``--resume RUN_DIR`` continues a run from its last complete checkpoint; ``--address``
joins an existing Ray cluster; ``--set key.sub=value`` overrides config keys.
Exit code 2 for a bad config or run directory, before anything is written.
"""

from __future__ import annotations

import argparse
import json
import logging
import shutil
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

import yaml

from league.config import RUN_CONFIG_FILE, ConfigError, RunConfig, load_config, saved_run_config
from league.coordinator import Coordinator, PhaseState, RunState, phase_count, phase_side
from league.evaluate import method_table
from league.evaluation import evaluate_pairs, format_table
from league.payoff import league_ratings
from league.progress import ProgressReporter
from league.store import DB_NAME, LeagueStore

EVALUATION_FILE = "evaluation.md"


class RunDirError(ValueError):
    pass


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m league.run", description=__doc__.splitlines()[0])
    parser.add_argument("--config", help="YAML file, or a name in configs/ (smoke, attacker_method2, ...)")
    parser.add_argument("--run-dir", type=Path, help="where to write the run (default runs/NAME-TIME)")
    parser.add_argument("--resume", type=Path, metavar="RUN_DIR", help="continue this run from its last checkpoint")
    parser.add_argument("--address", help="address of a running Ray cluster to join (e.g. auto, host:6379)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args(argv)
    if bool(args.config) == bool(args.resume):
        parser.error("give exactly one of --config and --resume")
    if args.resume and args.overrides:
        parser.error("--set applies to new runs only; a resumed run keeps its config")
    return args


def prepare_new_run_dir(run: RunConfig, run_dir: Path | None) -> Path:
    run_dir = run_dir or Path("runs") / f"{run.name}-{time.strftime('%Y%m%d-%H%M%S')}"
    if run_dir.exists() and any(run_dir.iterdir()):
        hint = " (use --resume to continue it)" if (run_dir / DB_NAME).exists() else ""
        raise RunDirError(f"run directory {run_dir} exists and is not empty{hint}")
    return run_dir


def start_ray(run: RunConfig, address: str | None) -> None:
    import ray

    if address:
        ray.init(address=address, logging_level=logging.ERROR, log_to_driver=False)
    else:
        ray.init(num_cpus=run.resources.num_cpus, include_dashboard=False, logging_level=logging.ERROR, log_to_driver=False)


def new_run(run: RunConfig, run_dir: Path) -> Coordinator:
    from league import rllib_bridge as bridge

    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / RUN_CONFIG_FILE).write_text(yaml.safe_dump(run.model_dump(mode="json"), sort_keys=False))
    store = LeagueStore(run_dir, create=True)
    with store.transaction():
        for method in run.attacker_methods:
            store.add_player(0, side="attacker", kind="learner", version=0, reward_method=method)
        store.add_player(0, side="team", kind="learner", version=0)
        for name in run.league.scripted_attackers:
            store.add_player(0, side="attacker", kind="scripted", version=0, scripted_attacker=name)
        for team in run.league.scripted_teams:
            store.add_player(
                0, side="team", kind="scripted", version=0, scripted_targeter=team.targeter, scripted_defender=team.defender
            )
    state = RunState(phase=PhaseState(index=0, side=phase_side(run, 0), start_iteration=0))
    first_attacker = store.players(side="attacker", kind="learner")[0]
    first_team = store.players(side="team", kind="scripted")[0]
    plan = bridge.MatchPlan([first_attacker.modules()], [[first_team.modules()]], [[1.0]], run.seed)
    algo = bridge.build_config(run, store.players(), plan).build_algo()
    coordinator = Coordinator(run, run_dir, store, algo, state)
    coordinator.rng = np.random.default_rng(run.seed)
    # The untrained policies join the league as version 0: the baseline every later
    # snapshot is measured against.
    initial = [coordinator.snapshot(learner) for learner in store.players(kind="learner")]
    checkpoint = coordinator.checkpoint()
    with store.transaction():
        for columns in initial:
            store.add_player(0, **columns)
        state.rng = coordinator.rng.bit_generator.state
        store.record_checkpoint(0, str(checkpoint.relative_to(run_dir)), json.dumps(asdict(state)))
    return coordinator


def read_run_config(run_dir: Path) -> RunConfig:
    if not (run_dir / DB_NAME).exists() or not (run_dir / RUN_CONFIG_FILE).exists():
        raise RunDirError(f"{run_dir} is not a league run directory (no {DB_NAME} or {RUN_CONFIG_FILE})")
    return saved_run_config(run_dir)


def resume_run(run_dir: Path) -> Coordinator:
    from ray.rllib.algorithms.algorithm import Algorithm

    run = read_run_config(run_dir)
    store = LeagueStore(run_dir)
    last = store.last_checkpoint()
    if last is None or not (run_dir / last[1]).exists():
        raise RunDirError(f"{run_dir} has no complete checkpoint to resume from")
    iteration, path, state_json = last
    store.rollback_after(iteration)
    kept = {run_dir / p for _, p in store.checkpoints()}
    for directory in (run_dir / "checkpoints").glob("iter_*"):
        if directory not in kept:  # partial, or written after the last commit
            shutil.rmtree(directory, ignore_errors=True)
    algo = Algorithm.from_checkpoint(str(run_dir / path))
    return Coordinator(run, run_dir, store, algo, RunState.from_json(state_json))


def evaluate_league(coordinator: Coordinator, progress: ProgressReporter) -> Path:
    """Every frozen attacker against every frozen team on the fixed evaluation games."""
    store, run = coordinator.store, coordinator.run
    frozen = [p for p in store.players() if p.kind != "learner"]
    attackers = [p for p in frozen if p.side == "attacker"]
    teams = [p for p in frozen if p.side == "team"]
    pairs = [(attacker, team) for attacker in attackers for team in teams]
    ev = run.evaluation
    results = evaluate_pairs(
        run.game, coordinator.run_dir, pairs, ev.episodes, ev.workers, ev.cpus_per_worker, coordinator.evaluation_pool,
        ev.custom_resources_per_worker, run.resources.torch_threads,
    )
    iteration = coordinator.state.iteration
    with store.transaction():
        for r in results:
            store.record_evaluation(iteration, r.outcome_rows())
        store.replace_ratings(iteration, league_ratings(store.counted_results(), [p.id for p in store.players()]))
        store.set_meta("evaluated_iteration", iteration)
    out = coordinator.run_dir / EVALUATION_FILE
    out.write_text(
        f"# Evaluation of {run.name} after iteration {iteration}\n\n"
        f"{run.evaluation.episodes} fixed games of scenario set `{run.game.scenario}` per pair; "
        "attacker win rate with its 95% Wilson interval.\n\n" + format_table(results)
        + "\n## Per attacker reward method\n\n" + method_table(results)
    )
    progress.evaluation(results, iteration)
    progress.message(f"evaluation of {len(results)} pairs written to {out}")
    return out


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        if args.resume:
            run_dir = args.resume.resolve()
            run = read_run_config(run_dir)
        else:
            run = load_config(args.config, args.overrides)
            run_dir = prepare_new_run_dir(run, args.run_dir).resolve()
    except (ConfigError, RunDirError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2

    import ray
    import torch

    torch.set_num_threads(run.resources.threads_for(1))  # the driver: learner, local env runner, evaluation
    start_ray(run, args.address)
    progress = None
    try:
        try:
            coordinator = resume_run(run_dir) if args.resume else new_run(run, run_dir)
        except RunDirError as err:
            print(f"error: {err}", file=sys.stderr)
            return 2
        progress = ProgressReporter(run_dir, phase_count(run))
        progress.message(f"run directory {run_dir} ({'resumed at iteration ' + str(coordinator.state.iteration) if args.resume else 'new'})")
        started = time.perf_counter()
        coordinator.train(progress)
        if coordinator.store.get_meta("evaluated_iteration") != coordinator.state.iteration:
            evaluate_league(coordinator, progress)
        if coordinator.evaluation_pool is not None:
            coordinator.evaluation_pool.close()
        progress.message(f"done in {time.perf_counter() - started:.0f} s: {run_dir}")
        coordinator.algo.stop()
        return 0
    finally:
        if progress is not None:
            progress.close()
        ray.shutdown()


if __name__ == "__main__":
    sys.exit(main())
