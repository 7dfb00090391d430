"""Train a league: ``python -m league.run --config attacker_method2.yaml``.

``--resume RUN_DIR`` continues a run from its newest intact checkpoint; ``--address``
joins an existing Ray cluster (without it the run starts a private Ray instance, even
when another cluster runs on the machine); ``--set key.sub=value`` overrides config keys.

Exit codes: 0 done; 2 a bad config, argument or run directory (one line on stderr,
nothing written), a run directory another process is training, a full disk, or an
``--address`` where no cluster answers within about 30 s or one that asks for a token;
130 / 143 stopped by SIGINT (Ctrl-C) / SIGTERM, with one line saying where the run
stopped and how to resume it. A new run that fails before its first checkpoint removes
what it wrote.
"""

from __future__ import annotations

import signal
import sys


def _stopped_while_importing(signum: int, frame: object) -> None:
    print("stopped while starting; nothing was written", file=sys.stderr)
    raise SystemExit(128 + signum)


if __name__ == "__main__":  # the imports below take seconds (torch, Ray); main() installs the real handlers
    for _signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(_signum, _stopped_while_importing)

import argparse
import logging
import os
import shutil
import time
from pathlib import Path

from league.cluster import ClusterError, check_cluster, quiet_node_deaths
from league.config import ConfigError, RunConfig, load_config
from league.training.lifecycle import (
    finish, finished_iteration, intact_checkpoints, new_run, phase_budgets, phase_count, resume_run, stopped_message,
)
from league.training.progress import ProgressReporter
from league.state.run_dir import (
    LOCK_FILE,
    RunDirError,
    check_config_unchanged,
    check_run_dir,
    disk_full_message,
    is_disk_full,
    lock_run,
    open_run,
    restore_damaged_database,
)
from league.training.stop import StopRequests, Stopped
from league.state.store import DB_NAME, LeagueStore
from league.cli import command_parser


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = command_parser(prog="python -m league.run", description=__doc__.splitlines()[0])
    parser.add_argument("--config", help="YAML file, or a name in configs/ (smoke, attacker_method2, ...)")
    parser.add_argument("--run-dir", type=Path, help="where to write the run (default runs/NAME-TIME)")
    parser.add_argument("--resume", type=Path, metavar="RUN_DIR", help="continue this run from its last checkpoint")
    parser.add_argument("--address", help="address of a running Ray cluster to join (e.g. auto, host:6379)")
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
        help="override a config key (dotted, the value read as YAML: --set ppo.lr=1e-3 --set 'ppo.hidden=[128, 128]'); "
        "repeatable; the keys are the fields of league/config.py (RunConfig)",
    )
    args = parser.parse_args(argv)
    if bool(args.config) == bool(args.resume):
        parser.error("give exactly one of --config and --resume")
    if args.resume and (args.overrides or args.run_dir):
        parser.error("--set and --run-dir apply to new runs only; a resumed run keeps its config and directory")
    return args


def prepare_new_run_dir(run: RunConfig, run_dir: Path | None) -> Path:
    run_dir = run_dir or Path("runs") / f"{run.name}-{time.strftime('%Y%m%d-%H%M%S')}"
    try:
        if run_dir.exists() and not run_dir.is_dir():
            raise RunDirError(f"--run-dir {run_dir} is a file, not a directory")
        if run_dir.exists() and any(p.name != LOCK_FILE for p in run_dir.iterdir()):
            hint = " (use --resume to continue it)" if (run_dir / DB_NAME).exists() else ""
            raise RunDirError(f"run directory {run_dir} exists and is not empty{hint}")
    except OSError as err:  # a folder on the way that this user may not read
        raise RunDirError(f"cannot use the run directory {run_dir}: {err.strerror or err}") from None
    return run_dir


def make_run_dir(run_dir: Path) -> None:
    """``mkdir -p run_dir``, or a ``RunDirError`` naming the path and why it cannot be made (a file
    on the way, no permission, ...), with the folders this call made before it failed removed."""
    to_make = [p for p in [run_dir, *run_dir.parents] if not os.path.exists(p)]  # deepest first
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        for path in to_make:
            try:
                path.rmdir()  # only an empty folder: one this call made
            except OSError:
                pass
        blocker = next((p for p in run_dir.parents if os.path.exists(p)), None)
        why = f"{blocker} is a file, not a directory" if blocker and not os.path.isdir(blocker) else err.strerror or str(err)
        raise RunDirError(f"cannot create the run directory {run_dir}: {why}") from None


def start_ray(run: RunConfig, address: str | None) -> None:
    import ray

    # "local": a private instance, even when RAY_ADDRESS is set or a `ray start` cluster runs here.
    where = {"address": address} if address else {
        "address": "local", "num_cpus": run.resources.num_cpus, "include_dashboard": False
    }
    try:
        ray.init(logging_level=logging.ERROR, log_to_driver=False, **where)
        if address:
            quiet_node_deaths()
    except SystemExit as exit_:
        if exit_.code == signal.SIGTERM:  # ray.init's own SIGTERM handler ends in sys.exit(15)
            raise Stopped(signal.SIGTERM) from None
        raise


def open_for_training(args: argparse.Namespace) -> tuple[RunConfig, Path, LeagueStore | None, object, bool]:
    """Validate everything and take the run directory's lock, before anything is written.

    Returns the config, the resolved run directory, the opened store (a resume), the
    held lock and whether this process created the directory."""
    if args.resume:
        run_dir = args.resume.resolve()
        check_run_dir(run_dir)
        lock = lock_run(run_dir)  # before reading: another process may be rolling the database back
        try:
            restored = restore_damaged_database(run_dir)
            if restored:
                print(restored, file=sys.stderr)
            run, store = open_run(run_dir)
            check_config_unchanged(run_dir, run, store)
            intact_checkpoints(run_dir, store)  # before Ray starts: fail fast
        except BaseException:
            lock.release()
            raise
        return run, run_dir, store, lock, False
    run = load_config(args.config, args.overrides)
    run_dir = prepare_new_run_dir(run, args.run_dir).resolve()
    created = not run_dir.exists()
    make_run_dir(run_dir)
    try:
        lock = lock_run(run_dir)
        prepare_new_run_dir(run, run_dir)  # again, under the lock: another run may have started here
    except BaseException:
        if created:
            shutil.rmtree(run_dir, ignore_errors=True)
        raise
    return run, run_dir, None, lock, created


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        run, run_dir, store, lock, created = open_for_training(args)
    except (ConfigError, RunDirError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    finished = finished_iteration(run_dir, store) if store is not None else None
    if finished is not None:  # nothing to resume: no Ray started
        print(f"{run_dir} is finished (iteration {finished}, evaluated); nothing to resume")
        store.close()
        lock.release()
        return 0
    stop = StopRequests()
    stop.install()

    import ray
    import torch

    torch.set_num_threads(run.resources.threads_for(1))  # the driver: learner, local env runner, evaluation
    progress = None
    try:
        address = check_cluster(args.address, stop.interruptible) if args.address else None  # one line, not a hang
        with stop.held_by_main_thread():
            start_ray(run, address)
            stop.install()
        stop.check()
        if args.resume:
            progress = ProgressReporter(run_dir, phase_count(run), phase_budgets=phase_budgets(run))
            coordinator = resume_run(run_dir, run, store, progress.message)
        else:
            coordinator = new_run(run, run_dir, stop)
            store = coordinator.store
            progress = ProgressReporter(run_dir, phase_count(run), phase_budgets=phase_budgets(run))
        progress.message(
            f"run directory {run_dir} ({'resumed at iteration ' + str(coordinator.state.iteration) if args.resume else 'new'})"
        )
        started = time.perf_counter()
        coordinator.train(progress, stop)
        finish(coordinator, progress, stop)
        total = time.perf_counter() - started
        progress.message(f"done in {total:.0f} s ({coordinator.time_split.summary(total)}): {run_dir}")
        return 0
    except (RunDirError, ClusterError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as interrupted:  # `Stopped`, or a library's own KeyboardInterrupt raised from it (`ray.get`)
        stopped = interrupted if isinstance(interrupted, Stopped) else Stopped(stop.signum or signal.SIGINT)
        stop.ignore()  # a second Ctrl-C must not break the shutdown below
        print(stopped_message(run_dir, store), file=sys.stderr)
        return stopped.exit_code
    except Exception as err:
        if not is_disk_full(err):
            raise
        stop.ignore()
        print(f"error: {disk_full_message(run_dir, store)}", file=sys.stderr)
        return 2
    finally:
        stop.ignore()
        if progress is not None:
            progress.close()
        ray.shutdown()
        lock.release()
        if created and store is None:  # a new run that failed before its first checkpoint
            shutil.rmtree(run_dir, ignore_errors=True)
        stop.restore()


if __name__ == "__main__":
    sys.exit(main())
