"""A study's training runs to their end as Ray Tune trials: ``train_runs``.

Each run (``TrainingRun``: config, run directory, overrides, label, log) is one trial of one
Tune experiment; the trial calls ``league.studies.runs.train_run``, so each run is still its
own ``python -m league.run`` process with its own private Ray instance (the same seed gives
the same run), its output appended to its log. A trial asks ``cpus_per_run`` CPUs of the Ray
instance that holds the trials, and at most ``jobs`` trials run at once.

* **Where.** Without ``address``: a Ray instance of this process's own (``jobs x
  cpus_per_run`` CPUs, no dashboard), shut down at the end (one already started in this
  process is used as it is); with ``address``: the Ray cluster
  there (checked first by the caller, ``league.cluster.check_cluster``), whose scheduler
  spreads the trials over its nodes. Run directories, logs and ``OUT/.tune`` must then be on
  storage every node reads and writes (a shared filesystem); Tune checks that it sees its
  own directory from each node.
* **Restarts.** The experiment is kept in ``OUT/.tune/runs-DIGEST`` (``DIGEST`` of the runs
  and the settings Tune pins: ``jobs``, ``cpus_per_run``). The same command again restores it
  (``Tuner.restore``): finished trials are not run again, errored and unfinished ones are
  run again, and ``train_run`` resumes each from its run's last checkpoint. The run
  directories are the truth: where the Tune state is missing, cannot be restored, or says
  finished of a run whose directory is not, a new experiment starts, and its trials reuse
  every finished run directory without training.
* **Output.** Tune's own console output is off; each trial's lines (``training ... ->``,
  ``resuming``, ``reusing``; on a cluster, ``LABEL: trained on node ID``) and the study's
  progress line (``progress_line``) are printed here, at the start and after each run.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import subprocess
import sys
import time
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Iterator

import ray
from ray import tune

from league.state.run_dir import RunDirError
from league.studies.runs import check_same_config, finished, train_run
from league.training.progress import duration

TUNE_DIR = ".tune"  # under the study's output directory
LINE, DONE = "line", "done"  # the keys of a trial's two kinds of report
# Tune's console output off: its new output engine prints an experiment table whatever the
# verbosity; the old one, at verbosity 0, nothing. Trials keep their working directory (a
# trial's league.run then imports the code the study runs, and relative paths stay valid).
TUNE_ENVIRONMENT = {"RAY_AIR_NEW_OUTPUT": "0", "RAY_CHDIR_TO_TRIAL_DIR": "0"}


@dataclass(frozen=True)
class TrainingRun:
    """One run of a study: ``config`` with ``overrides`` (``--set`` items) trained into
    ``run_dir``; ``label`` names it in lines, its ``league.run`` output goes to ``log``."""

    config: str
    run_dir: Path
    overrides: tuple[str, ...]
    label: str
    log: Path


@dataclass(frozen=True)
class Trained:
    """What a trial did: the run, whether it was finished before (``reused``), its trial's
    seconds, and the id of the Ray node it ran on."""

    run: TrainingRun
    reused: bool
    seconds: float
    node: str


class RunFailed(Exception):
    """A run's training failed or was stopped; the same command again resumes it."""


def progress_line(total: int, done: int, reused: int, trained_seconds: list[float], elapsed: float,
                  parallel: int) -> str:
    """``study: 3 of 10 runs done (2 reused), 41 min elapsed, about 1 h 20 min left``.

    The time left is the runs left, ``parallel`` at a time, at the mean duration of the runs
    trained (or resumed) in this process (``trained_seconds``): reused runs took no time
    and say nothing of the speed, so with none trained yet the time left is unknown."""
    line = f"study: {done} of {total} runs done ({reused} reused), {duration(elapsed)} elapsed"
    left = total - done
    if not left:
        return line
    if not trained_seconds:
        return f"{line}, time left unknown until a run has trained here"
    rounds = -(-left // max(1, min(parallel, left)))  # whole rounds of `parallel` runs
    return f"{line}, about {duration(rounds * sum(trained_seconds) / len(trained_seconds))} left"


def say(line: str) -> None:
    """One line in one write, at once (the study's lines between its runs' long silences)."""
    sys.stdout.write(line + "\n")
    sys.stdout.flush()


def trial(params: dict[str, Any]) -> None:
    """The Tune trainable: one run to its end (``train_run``). Reports each of ``train_run``'s
    lines, then whether the run was finished before, the seconds and the node."""
    run = params["run"]
    run_dir = Path(run["run_dir"])
    reused = finished(run_dir)
    started = time.monotonic()
    train_run(run["config"], run_dir, run["overrides"], run["label"], Path(run["log"]),
              say=lambda line: tune.report({LINE: line}))
    tune.report({DONE: True, "reused": reused, "seconds": time.monotonic() - started,
                 "node": ray.get_runtime_context().get_node_id()})


def trial_dirname(trial: Any) -> str:
    """A trial's folder under the experiment: its id (Tune's default spells out the whole config)."""
    return f"trial-{trial.trial_id}"


class StudyProgress(tune.Callback):
    """Prints each trial's lines and the study's progress line (at the start and after each run).

    Tune keeps this callback in its experiment state and restores it with the experiment,
    so the counts and the clock start in ``setup``, at the start of every ``fit``."""

    def __init__(self, runs: list[TrainingRun], parallel: int, on_cluster: bool):
        self.runs, self.parallel, self.on_cluster = runs, parallel, on_cluster

    def setup(self, **info: Any) -> None:
        self.started = time.monotonic()
        # absolute, as the trials' parameters name them (`param`): a relative --out counted each reused run twice
        self.done = {str(r.run_dir.resolve()) for r in self.runs if finished(r.run_dir)}
        self.reused = len(self.done)
        self.trained: list[float] = []
        self.show()

    def show(self) -> None:
        say(progress_line(len(self.runs), len(self.done), self.reused, self.trained,
                          time.monotonic() - self.started, self.parallel))

    def on_trial_result(self, iteration: int, trials: list, trial: Any, result: dict, **info: Any) -> None:
        if LINE in result:
            say(result[LINE])

    def on_trial_complete(self, iteration: int, trials: list, trial: Any, **info: Any) -> None:
        result, run_dir = trial.last_result, trial.config["run"]["run_dir"]
        if result.get(DONE) and run_dir not in self.done:
            self.done.add(run_dir)
            if result["reused"]:
                self.reused += 1
            else:
                self.trained.append(result["seconds"])
                if self.on_cluster:
                    say(f"{trial.config['run']['label']}: trained on node {result['node']}")
        self.show()

    def on_trial_error(self, iteration: int, trials: list, trial: Any, **info: Any) -> None:
        run = trial.config["run"]
        say(f"{run['label']} failed ({run['run_dir']}; its output: {run['log']})")


def experiment_name(runs: list[TrainingRun], jobs: int | None, cpus_per_run: float, on_cluster: bool) -> str:
    """The experiment's folder: a digest of everything Tune pins when it restores it."""
    pinned = json.dumps([[param(r) for r in runs], jobs, cpus_per_run, on_cluster], sort_keys=True)
    return "runs-" + hashlib.sha256(pinned.encode()).hexdigest()[:12]


def param(run: TrainingRun) -> dict[str, Any]:
    """A run as a trial's parameter: plain values, absolute paths (a trial runs where Ray puts it)."""
    values = asdict(run)
    values.update(run_dir=str(run.run_dir.resolve()), log=str(run.log.resolve()), overrides=list(run.overrides))
    return values


def restored(path: Path, trainable: Any) -> tune.Tuner | None:
    """The experiment at ``path`` restored, or ``None`` where there is none, it cannot be read,
    or it says finished of a run whose directory is not (the run directories are the truth)."""
    if not tune.Tuner.can_restore(str(path)):
        return None
    try:
        tuner = tune.Tuner.restore(str(path), trainable, resume_unfinished=True, resume_errored=True)
        stale = [r for r in tuner.get_results()
                 if r.metrics and r.metrics.get(DONE) and not finished(Path(r.config["run"]["run_dir"]))]
    except Exception as err:  # a state cut short by a kill, or of another Ray version
        say(f"starting the study's trials afresh: its Tune state in {path} cannot be restored ({err})")
        return None
    if stale:
        say(f"starting the study's trials afresh: its Tune state in {path} says finished of runs that are not")
        return None
    return tuner


def train_runs(runs: list[TrainingRun], out: Path, jobs: int | None = None, cpus_per_run: float = 2.0,
               address: str | None = None) -> list[Trained]:
    """Train every run to its end as a Ray Tune trial (the module's docstring), ``jobs`` at once
    (``None``: 1 here, as many as the cluster's CPUs hold at ``address``), ``cpus_per_run`` CPUs
    each; the experiment kept in ``out/.tune``. Returns what each trial did, in ``runs``' order.

    Raises ``RunDirError`` for a run directory of another config (before any trial starts) or
    one that another process trains, ``RunFailed`` for a run that failed or was stopped."""
    for run in runs:  # all refused before anything trains, as one run of a sequential loop would be
        check_same_config(run.config, run.run_dir, list(run.overrides))
    for run in runs:
        run.log.parent.mkdir(parents=True, exist_ok=True)
    started_ray = not ray.is_initialized()
    if started_ray:
        if address:
            ray.init(address=address, logging_level=logging.ERROR, log_to_driver=False)
        else:
            ray.init(address="local", num_cpus=(jobs or 1) * cpus_per_run, include_dashboard=False,
                     logging_level=logging.ERROR, log_to_driver=False)
    try:
        with quiet_tune():
            return fit(runs, out, jobs if jobs or address else 1, cpus_per_run, on_cluster=address is not None)
    finally:
        if started_ray:
            ray.shutdown()


def training_exit_code(runs: list[TrainingRun], out: Path, jobs: int | None = None, cpus_per_run: float = 2.0,
                       address: str | None = None) -> int:
    """``train_runs`` for a command: 0 every run finished; 2 a run directory it cannot use, 1 a run that failed
    or was stopped (the same command again resumes it), each with one line on stderr."""
    try:
        train_runs(runs, out, jobs, cpus_per_run, address)
    except RunDirError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except RunFailed as err:
        print(f"error: {err}; run this command again to resume", file=sys.stderr)
        return 1
    return 0


@contextmanager
def quiet_tune() -> Iterator[None]:
    """Tune's console output off meanwhile (``TUNE_ENVIRONMENT``, read by Tune in this process and
    passed on to the trials), and its log of a failed trial's traceback: the run's log has it."""
    saved = {key: os.environ.get(key) for key in TUNE_ENVIRONMENT}
    tune_logger = logging.getLogger("ray.tune")
    level = tune_logger.level
    os.environ.update(TUNE_ENVIRONMENT)
    tune_logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        tune_logger.setLevel(level)
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def fit(runs: list[TrainingRun], out: Path, jobs: int | None, cpus_per_run: float, on_cluster: bool) -> list[Trained]:
    """``train_runs`` once Ray is up: restore or start the experiment, fit it, read the outcome."""
    trainable = tune.with_resources(trial, {"cpu": cpus_per_run})
    path = (out / TUNE_DIR).resolve() / experiment_name(runs, jobs, cpus_per_run, on_cluster)
    tuner = restored(path, trainable)
    if tuner is None:
        shutil.rmtree(path, ignore_errors=True)
        parallel = jobs or max(1, int(ray.cluster_resources().get("CPU", 1) // cpus_per_run))
        tuner = tune.Tuner(
            trainable,
            param_space={"run": tune.grid_search([param(r) for r in runs])},
            tune_config=tune.TuneConfig(max_concurrent_trials=jobs, trial_dirname_creator=trial_dirname),
            run_config=tune.RunConfig(storage_path=str(path.parent), name=path.name, verbose=0,
                                      callbacks=[StudyProgress(runs, parallel, on_cluster)]),
        )
    grid = tuner.fit()
    by_dir = {r.config["run"]["run_dir"]: r for r in grid if r.config}
    outcome, failed = [], []
    for run in runs:
        result = by_dir.get(param(run)["run_dir"])
        if result is not None and result.error is not None:
            failed.append((run, getattr(result.error, "cause", result.error)))
        elif result is None or not result.metrics.get(DONE) or not finished(run.run_dir):
            failed.append((run, None))
        else:
            metrics = result.metrics
            outcome.append(Trained(run, metrics["reused"], metrics["seconds"], metrics["node"]))
    for run, error in failed:
        if isinstance(error, RunDirError):
            raise RunDirError(str(error)) from None
    if failed:
        raise RunFailed("; ".join(why(run, error) for run, error in failed))
    return outcome


def why(run: TrainingRun, error: BaseException | None) -> str:
    """A failed run in a few words: what ended it and where its output is."""
    if isinstance(error, subprocess.CalledProcessError):
        return f"training {run.label} failed (league.run exit {error.returncode}; its output: {run.log})"
    if error is not None:
        first = str(error).splitlines()[0] if str(error) else ""
        return f"training {run.label} failed ({type(error).__name__}: {first}; its output: {run.log})"
    return f"training {run.label} was stopped before its end"
