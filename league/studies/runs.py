"""Training runs of a study to their end, restartable: a finished run is reused, an unfinished one resumed
from its last checkpoint, a new one started (each as ``python -m league.run`` in its own process)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

from league.config import RUN_CONFIG_FILE, added_at_its_default, changed_keys, load_config
from league.state.run_dir import EVALUATION_FILE, RunDirError, lock_run, read_config


def finished(run_dir: Path) -> bool:
    """A run whose training and final evaluation completed (``evaluation.md`` is written last)."""
    return (run_dir / EVALUATION_FILE).exists()


def resumable(run_dir: Path) -> bool:
    checkpoints = run_dir / "checkpoints"
    return (run_dir / "league.db").exists() and checkpoints.is_dir() and any(
        not p.name.endswith(".partial") for p in checkpoints.glob("iter_*")
    )


def say(line: str) -> None:
    """One line in one write: ``--jobs`` trains from several threads, and ``print`` writes
    the text and its newline apart (two runs' lines ran together)."""
    sys.stdout.write(line + "\n")
    sys.stdout.flush()


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


def train_run(config: str, run_dir: Path, overrides, label: str, log: Path | None = None) -> None:
    """Train a ``league.run`` to the end: skip it when finished, resume it when it has a
    checkpoint, else start it from ``config`` with ``overrides`` (``--set`` items); a run made
    from another config is refused (``RunDirError``)."""
    check_same_config(config, run_dir, overrides)
    if finished(run_dir):
        say(f"reusing {run_dir} (finished)")
        return
    out = open(log, "a") if log else None
    try:
        if resumable(run_dir):
            say(f"resuming {run_dir}")
            subprocess.run([sys.executable, "-m", "league.run", "--resume", str(run_dir)], stdout=out, stderr=out, check=True)
            return
        if run_dir.exists():  # killed before its first checkpoint: nothing to resume
            lock_run(run_dir).release()  # refuses (RunDirError) while another process trains it
            shutil.rmtree(run_dir)
        command = [sys.executable, "-m", "league.run", "--config", config, "--run-dir", str(run_dir)]
        for item in overrides:
            command += ["--set", item]
        say(f"training {label} -> {run_dir}")
        subprocess.run(command, stdout=out, stderr=out, check=True)
    finally:
        if out:
            out.close()


def _train_here(config: str, run_dir: str, overrides, label: str, log: str | None) -> str:
    """One run, trained on whichever node Ray placed this task; the node's id."""
    import ray

    train_run(config, Path(run_dir), overrides, label, Path(log) if log else None)
    return ray.get_runtime_context().get_node_id()


def train_runs_on_cluster(address: str, runs: list[tuple], cpus_per_run: float) -> list[str]:
    """Train every ``(config, run_dir, overrides, label, log)`` as a Ray task of the cluster at
    ``address`` (``ray.init(address=...)``), ``cpus_per_run`` CPUs each, so Ray spreads the runs
    over its nodes; each run is still its own ``league.run`` process with its own private Ray
    instance on its node. Run directories must be on storage every node reads and writes (a
    shared filesystem). Returns the node id each run trained on, in order."""
    import ray

    ray.init(address=address, logging_level="ERROR")
    try:
        task = ray.remote(num_cpus=cpus_per_run)(_train_here)
        refs = [task.remote(config, str(Path(d).resolve()), tuple(o), label, str(Path(log).resolve()) if log else None)
                for config, d, o, label, log in runs]
        return ray.get(refs)
    finally:
        ray.shutdown()
