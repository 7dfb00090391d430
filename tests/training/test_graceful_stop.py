"""A graceful stop (SIGTERM, Ctrl-C) finishes the iteration under way and checkpoints it: the
resumed run goes on from there and ends as the run never stopped (its league database, but
the stop's extra checkpoint row, and every saved player's weights)."""

import signal
import time
from pathlib import Path

import pytest

from league.state.run_dir import run_differences
from league.state.store import LeagueStore
from tests.training.test_same_seed import RUN_TIMEOUT, TINY_SMOKE, finish, iterations, league

# The tiny smoke league with a checkpoint only where a phase ends: a stop between two of them
# used to lose every iteration since the last one.
RARE_CHECKPOINTS = [*TINY_SMOKE, "--set", "checkpoint_every=1000", "--set", "league.selfplay_phases=3"]
STOP_AFTER = 4  # committed iterations before the signal: inside the second phase, whose checkpoint comes at its end


def checkpoint_rows(run_dir: Path) -> list[tuple]:
    store = LeagueStore(run_dir)
    try:
        return store.contents()["checkpoints"]
    finally:
        store.close()


@pytest.fixture(scope="module")
def stopped_and_whole(tmp_path_factory) -> tuple[Path, Path, int, str]:
    """The same run twice, side by side: one stopped by SIGTERM after ``STOP_AFTER`` iterations and
    resumed, one never stopped; with the stopped iteration and the stop's last line."""
    base = tmp_path_factory.mktemp("graceful_stop")
    stopped, whole = base / "stopped", base / "whole"
    proc = league(*RARE_CHECKPOINTS, "--run-dir", str(stopped))
    uninterrupted = league(*RARE_CHECKPOINTS, "--run-dir", str(whole))
    deadline = time.monotonic() + RUN_TIMEOUT
    while iterations(stopped) < STOP_AFTER:
        assert proc.poll() is None, proc.stdout.read()[-3000:]
        assert time.monotonic() < deadline, f"the run did not reach iteration {STOP_AFTER} in time"
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)  # a scheduler's SIGTERM to the run's process
    out, _ = proc.communicate(timeout=RUN_TIMEOUT)
    assert proc.returncode == 143, out[-3000:]
    at = iterations(stopped)
    last_line = out.strip().splitlines()[-1]
    resumed = finish(league("--resume", str(stopped)))
    assert f"resumed at iteration {at}" in resumed, resumed[-2000:]
    finish(uninterrupted)
    return stopped, whole, at, last_line


def test_a_stopped_run_ends_with_a_checkpoint_of_its_last_iteration(stopped_and_whole):
    stopped, _, at, last_line = stopped_and_whole
    assert last_line == (
        f"stopped at iteration {at}, last checkpoint {at}, resume with `python -m league.run --resume {stopped}`"
    )
    assert at % 1000 != 0 and at in [row[0] for row in checkpoint_rows(stopped)]


def test_the_resumed_run_is_the_run_never_stopped(stopped_and_whole):
    stopped, whole, at, _ = stopped_and_whole
    # The one difference: the stop's checkpoint, which the uninterrupted run did not write.
    assert run_differences(whole, stopped) == [
        f"checkpoints: {len(checkpoint_rows(whole))} and {len(checkpoint_rows(stopped))} rows, "
        f"first differing: {[row for row in checkpoint_rows(stopped) if row[0] == at]}"
    ]
    assert [row for row in checkpoint_rows(stopped) if row[0] != at] == checkpoint_rows(whole)
    assert iterations(stopped) == iterations(whole) > at
