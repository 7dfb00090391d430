"""Same config and seed, same run: two runs of the smoke league, and one killed twice and
resumed, end with the same league database (but its wall-clock columns) and the same weights."""

import os
import random
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from league.state.run_dir import run_differences

# The smoke league at a tiny budget: two phases of a few iterations, with learning curves and
# a checkpoint after every iteration (a kill lands anywhere in one).
TINY_SMOKE = [
    "--config", "smoke",
    "--set", "ppo.train_batch_size=1024", "--set", "ppo.minibatch_size=256",
    "--set", "resources.num_envs_per_env_runner=32",
    "--set", "league.phase_env_steps=3072", "--set", "league.selfplay_phases=2",
    "--set", "evaluation.episodes=20", "--set", "evaluation.curve_episodes=20",
    "--set", "evaluation.curve_every_env_steps=1024",
    "--set", "evaluation.workers=0",  # the same numbers as on workers (tests/evaluation/test_engine.py), without their start-up
    "--set", "checkpoint_every=1",
]
RUN_TIMEOUT = 600


def league(*args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "league.run", *args],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True,  # its own process group: a kill reaches only this run and its Ray
    )


def finish(proc: subprocess.Popen) -> str:
    out, _ = proc.communicate(timeout=RUN_TIMEOUT)
    assert proc.returncode == 0, out[-3000:]
    return out


def iterations(run_dir: Path) -> int:
    if not (run_dir / "league.db").exists():
        return 0
    with sqlite3.connect(run_dir / "league.db", timeout=30) as db:
        return db.execute("SELECT COUNT(*) FROM iterations").fetchone()[0]


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> tuple[Path, Path]:
    """Two uninterrupted runs of the tiny smoke league, side by side (each has a process and a Ray of its own)."""
    base = tmp_path_factory.mktemp("same_seed")
    procs = [league(*TINY_SMOKE, "--run-dir", str(base / name)) for name in ("whole", "second")]
    for proc in procs:
        finish(proc)
    assert iterations(base / "whole") >= 4
    return base / "whole", base / "second"


@pytest.fixture(scope="module")
def whole(runs) -> Path:
    return runs[0]


def test_two_runs_with_one_seed_are_one_run(runs):
    assert run_differences(*runs) == []


def test_a_run_killed_twice_and_resumed_is_the_run_never_killed(whole, tmp_path):
    killed = tmp_path / "killed"
    total = iterations(whole)
    moments = random.Random(0)
    proc = league(*TINY_SMOKE, "--run-dir", str(killed))
    for after in (1, 3):  # SIGKILL somewhere in the iteration after `after` committed ones
        deadline = time.monotonic() + RUN_TIMEOUT
        while iterations(killed) < after:
            assert proc.poll() is None, proc.stdout.read()[-3000:]
            assert time.monotonic() < deadline, f"the run did not reach iteration {after} in time"
            time.sleep(0.05)
        time.sleep(moments.uniform(0.0, 1.0))
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=60)
        assert iterations(killed) < total, "the run ended before it was killed"
        proc = league("--resume", str(killed))
    assert "resumed at iteration" in finish(proc)
    assert run_differences(whole, killed) == []
    assert not list((killed / "checkpoints").glob("*.partial"))


def test_a_run_with_remote_env_runners_killed_and_resumed_is_the_run_never_killed(tmp_path):
    # RLlib's restore left the remote runners with the weights they were built with (the priors):
    # the resumed run's next iteration played other games (``bridge.restore_algorithm``).
    remote = [*TINY_SMOKE, "--set", "resources.num_env_runners=2"]
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    finish(league(*remote, "--run-dir", str(whole)))
    # killed within the first phase: the next iteration samples with the restored weights
    killed_after_two_and_resumed(remote, whole, killed)
    assert run_differences(whole, killed) == []


def test_a_run_with_the_teams_own_epoch_count_killed_and_resumed_is_the_run_never_killed(whole, tmp_path):
    # Killed in the attacker's phase: the resumed run's team phase must pass its batches twice.
    tiny = [*TINY_SMOKE, "--set", "ppo.team_num_epochs=2"]
    own, killed = tmp_path / "own", tmp_path / "killed"
    finish(league(*tiny, "--run-dir", str(own)))
    assert run_differences(whole, own) != []  # the setting changes the run
    killed_after_two_and_resumed(tiny, own, killed)
    assert run_differences(own, killed) == []


def killed_after_two_and_resumed(args: list[str], whole: Path, killed: Path) -> None:
    """Start the run ``args`` at ``killed``, SIGKILL it once 2 iterations are committed, resume it to its end."""
    proc = league(*args, "--run-dir", str(killed))
    deadline = time.monotonic() + RUN_TIMEOUT
    while iterations(killed) < 2:
        assert proc.poll() is None, proc.stdout.read()[-3000:]
        assert time.monotonic() < deadline, "the run did not reach iteration 2 in time"
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=60)
    assert iterations(killed) < iterations(whole), "the run ended before it was killed"
    assert "resumed at iteration" in finish(league("--resume", str(killed)))


def test_resume_restores_a_truncated_database_and_ends_as_the_run_never_damaged(whole, tmp_path):
    damaged = tmp_path / "damaged"
    shutil.copytree(whole, damaged)
    with open(damaged / "league.db", "r+b") as db:
        db.truncate(4096)
    out = finish(league("--resume", str(damaged)))
    said = [line for line in out.splitlines() if "restored it from" in line]
    assert len(said) == 1 and "league.db is damaged" in said[0] and "checkpoints/iter_" in said[0], out[-2000:]
    assert run_differences(whole, damaged) == []
