"""Shared fixtures: one tiny finished league run for the tests that read a run directory, and a
private Ray instance per test module for the tests that play or train in this process."""

import atexit
import os
import shutil
import subprocess
import sys

import pytest

TINY_RUN = """
name: tiny
seed: 3
ppo: {train_batch_size: 300, minibatch_size: 100, num_epochs: 2, hidden: [32, 32]}
resources: {num_cpus: 2, num_env_runners: 0, num_envs_per_env_runner: 4}
league: {mode: selfplay, selfplay_phases: 2, min_phase_episodes: 100000, phase_env_steps: 600}
evaluation: {episodes: 10, every_iterations: 2, curve_every_env_steps: 300, curve_episodes: 20}
"""


@pytest.fixture(scope="session")
def tiny_run_once(tmp_path_factory):
    """The tiny run, trained once per test process; tests take it through ``tiny_run``."""
    base = tmp_path_factory.mktemp("tiny_run")
    (base / "tiny.yaml").write_text(TINY_RUN)
    run = base / "run"
    proc = subprocess.run(
        [sys.executable, "-m", "league.run", "--config", str(base / "tiny.yaml"), "--run-dir", str(run)],
        capture_output=True, text=True,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    (base / "run.log").write_text(proc.stderr)  # its progress lines, as a log file would hold them
    return run


def tree_state(root):
    """Every file under ``root`` with its size and modification time: what a write changes.

    A reader of league.db leaves SQLite's shared-memory index and an empty write-ahead log
    while its connection is open; only a log with frames in it is a write."""
    state = {}
    for path in sorted(root.rglob("*")):
        stat = path.stat()
        if path.is_file() and not path.name.endswith("-shm") and not (path.name.endswith("-wal") and stat.st_size == 0):
            state[str(path.relative_to(root))] = (stat.st_size, stat.st_mtime_ns)
    return state


@pytest.fixture
def tiny_run(tiny_run_once):
    """A finished two-phase self-play run (attacker-m2-v0/v1, team-v0/v1), shared by the tests
    of this process: a test that writes into it errors at teardown (take ``run_copy`` to change
    a run), so that no test's result depends on which tests ran before it."""
    before = tree_state(tiny_run_once)
    yield tiny_run_once
    after = tree_state(tiny_run_once)
    changed = sorted(name for name in before.keys() | after.keys() if before.get(name) != after.get(name))
    assert not changed, f"this test wrote into the shared tiny run (use run_copy): {changed}"


@pytest.fixture
def run_copy(tiny_run_once, tmp_path):
    """A copy of the tiny run that a test may change."""
    copy = tmp_path / "run"
    shutil.copytree(tiny_run_once, copy)
    return copy


@pytest.fixture(scope="module")
def ray_instance():
    """A Ray instance of this test module's own (2 CPUs, no dashboard), started for its first
    test that asks and shut down once the module's tests are done.

    ``address="local"`` starts a new instance whatever else runs (a cluster named by
    ``RAY_ADDRESS``, another module's or another process's instance). A fixture that builds
    on Ray asks for this one, so that pytest stops what it built before Ray.
    """
    import ray  # here: the modules that never start Ray do not import it

    # No worker output forwarded, as in the commands: a trial's exit noise is not the command's stderr.
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def pytest_sessionfinish(session, exitstatus):
    """End the test process with pytest's status before the interpreter tears down.

    ``ray.shutdown()`` leaves Ray's native threads running in this process (gRPC timers,
    the GCS client's and the core worker's io threads: 9 of them after the Ray tests of one
    module). Interpreter teardown with them alive crashed a CI run once, after all 305
    tests had passed (exit 139, segmentation fault). Run last, as the first atexit
    handler, this exit skips that teardown; every test, report and pytest cleanup has
    finished by then. Processes that train (``league.run``) start Ray once and exit normally.
    """
    def exit_now():
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(int(exitstatus))

    atexit.register(exit_now)
