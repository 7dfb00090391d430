"""One training run of a study to its end, restartable: a finished run is reused, an unfinished one resumed
from its last checkpoint, a new one started (as ``python -m league.run`` in its own process, with its own
Ray instance). ``league.studies.trials`` trains a study's runs so, each as a Ray Tune trial."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path
from typing import Callable

from league.config import RUN_CONFIG_FILE, added_at_its_default, changed_keys, load_config
from league.state.run_dir import EVALUATION_FILE, RunDirError, lock_run, open_run, read_config


def finished(run_dir: Path) -> bool:
    """A run whose training and final evaluation completed (``evaluation.md`` is written last)."""
    return (run_dir / EVALUATION_FILE).exists()


def resumable(run_dir: Path) -> bool:
    checkpoints = run_dir / "checkpoints"
    return (run_dir / "league.db").exists() and checkpoints.is_dir() and any(
        not p.name.endswith(".partial") for p in checkpoints.glob("iter_*")
    )


def check_same_config(config: str, run_dir: Path, overrides) -> None:
    """Refuse to reuse or resume a run made from another config than ``config`` with ``overrides``
    (a study that spans sessions must not mix runs of an edited config with new ones)."""
    if not (run_dir / RUN_CONFIG_FILE).exists():
        return
    old, new = read_config(run_dir).model_dump(mode="json"), load_config(config, list(overrides)).model_dump(mode="json")
    keys = [key for key in changed_keys(old, new) if not added_at_its_default(old, new, key)]
    if keys:
        raise RunDirError(f"{run_dir} was trained with another config ({', '.join(keys)} differ from {config} "
                          "with these overrides): move it away, or give the study another --out")


def train_run(config: str, run_dir: Path, overrides, label: str, log: Path | None, say: Callable[[str], None]) -> None:
    """Train a ``league.run`` to the end: skip it when finished, resume it when it has a
    checkpoint, else start it from ``config`` with ``overrides`` (``--set`` items), its output
    appended to ``log`` (``None``: this process's); ``say`` hears which of the three it does.
    A run made from another config is refused (``RunDirError``), a failed ``league.run``
    raises ``CalledProcessError``."""
    check_same_config(config, run_dir, overrides)
    if finished(run_dir):
        say(f"reusing {run_dir} (finished)")
        return
    if resumable(run_dir):
        say(f"resuming {run_dir}")
        run_saying_progress([sys.executable, "-m", "league.run", "--resume", str(run_dir)], log, label, say)
        return
    if run_dir.exists():  # killed before its first checkpoint: nothing to resume
        lock_run(run_dir).release()  # refuses (RunDirError) while another process trains it
        shutil.rmtree(run_dir)
    command = [sys.executable, "-m", "league.run", "--config", config, "--run-dir", str(run_dir)]
    for item in overrides:
        command += ["--set", item]
    say(f"training {label} -> {run_dir}")
    run_saying_progress(command, log, label, say)


PROGRESS_EVERY_S = 60.0  # how often a run whose output goes to a log passes on its newest training line


def run_saying_progress(command: list[str], log: Path | None, label: str, say: Callable[[str], None]) -> None:
    """Run ``command`` to its end, its output appended to ``log`` (``None``: this process's);
    with a log, every ``PROGRESS_EVERY_S`` its newest line that tells the share of the budget
    done and the time left goes to ``say``, prefixed by ``label`` (a study's only sign of life
    during a long run). A failure raises ``CalledProcessError``; an interruption here ends the
    run's process too, as ``subprocess.run`` does."""
    out = open(log, "a") if log else None
    try:
        with subprocess.Popen(command, stdout=out, stderr=out) as proc:
            try:
                while not wait_for(proc, PROGRESS_EVERY_S if log else None):
                    line = newest_progress_line(log) if log else None
                    if line:
                        say(f"{label}: {line}")
            except BaseException:
                proc.kill()
                raise
    finally:
        if out:
            out.close()
    if proc.returncode:
        raise subprocess.CalledProcessError(proc.returncode, command)


def wait_for(proc: subprocess.Popen, seconds: float | None) -> bool:
    """Whether ``proc`` ended within ``seconds`` (``None``: wait for it)."""
    try:
        proc.wait(timeout=seconds)
    except subprocess.TimeoutExpired:
        return False
    return True


def newest_progress_line(log: Path) -> str | None:
    """The last training line in the log's last 64 KiB that says the share of the budget done (``| 35% of``)."""
    with open(log, "rb") as f:
        f.seek(max(0, f.seek(0, 2) - 65536))
        lines = f.read().decode(errors="replace").splitlines()
    return next((line.strip() for line in reversed(lines) if "% of " in line and " left" in line), None)



def speed(run_dir: Path) -> str:
    """A finished run's training: env steps, training seconds and env steps per second."""
    _, store = open_run(run_dir)
    try:
        steps, seconds = store.last_iteration()["env_steps"], store.training_seconds()
    finally:
        store.close()
    return f"{steps:,} env steps in {seconds:.0f} s of training iterations ({steps / seconds:,.0f} env steps/s)"
