"""``league.reproduce``: budgets and variants become valid configs; restarts reuse and resume runs."""

import os
import signal
import subprocess
import sys
import time

import pytest

from league.config import load_config
from league.studies.table_one import Budget, phases_override
from league.state.run_dir import lock_holder
from league.state.store import LeagueStore

TINY = [
    "--set", "ppo.train_batch_size=300", "--set", "ppo.minibatch_size=100", "--set", "resources.num_envs_per_env_runner=4",
    "--set", "evaluation.curve_every_env_steps=300", "--set", "evaluation.curve_episodes=20", "--set", "evaluation.workers=0",
]


@pytest.mark.parametrize("team", [False, True])
def test_a_budget_in_env_steps_replaces_the_episode_counts_of_the_phases(team):
    run = load_config("attacker_method2_paper", [phases_override(Budget("env_steps", 5000), team)])
    assert [(p.learner, p.episodes, p.env_steps, p.opponents) for p in run.league.phases] == [
        ("attacker", None, 5000, "scripted"), *([("team", None, 5000, "latest")] if team else [])
    ]
    assert load_config("attacker_method2_paper", [phases_override(Budget("episodes", 30), False)]).league.phases[0].episodes == 30


def reproduce(out, *extra, wait=True):
    command = [sys.executable, "-m", "league.reproduce", "--seeds", "1", "--methods", "2", "--env-steps", "1500",
               "--evaluation-episodes", "20", "--out", str(out), *TINY, "--set", "checkpoint_every=1", *extra]
    if not wait:
        return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return subprocess.run(command, capture_output=True, text=True)


def committed_iterations(run_dir):
    if not (run_dir / "league.db").exists():
        return []
    store = LeagueStore(run_dir)
    try:
        return [row["iteration"] for row in store.iteration_rows()]
    finally:
        store.close()


def test_a_restart_resumes_a_killed_run_and_reuses_finished_ones(tmp_path):
    run_dir = tmp_path / "paper" / "env-steps-1500" / "method2-seed0"
    first = reproduce(tmp_path, wait=False)
    deadline = time.monotonic() + 600
    while not committed_iterations(run_dir):  # its first of 5 iterations committed: kill it mid-run
        assert first.poll() is None and time.monotonic() < deadline, first.communicate()
        time.sleep(0.5)
    os.kill(lock_holder(run_dir), signal.SIGKILL)
    _, err = first.communicate(timeout=120)
    assert first.returncode == 1 and "run this command again to resume" in err
    assert not (run_dir / "evaluation.md").exists()

    resumed = reproduce(tmp_path)
    assert resumed.returncode == 0, resumed.stdout[-2000:] + resumed.stderr[-2000:]
    assert f"resuming {run_dir}" in resumed.stdout and "training paper" not in resumed.stdout
    assert committed_iterations(run_dir) == [1, 2, 3, 4, 5]  # continued, nothing done twice
    table = (tmp_path / "paper" / "env-steps-1500" / "table1.md").read_text()
    assert "1,500 env steps of training" in table and "| 2 | " in table
    assert (tmp_path / "paper" / "env-steps-1500" / "curves-method2" / "curves.png").exists()

    db_mtime = (run_dir / "league.db").stat().st_mtime
    again = reproduce(tmp_path)
    assert again.returncode == 0 and f"reusing {run_dir} (finished)" in again.stdout
    assert (run_dir / "league.db").stat().st_mtime == db_mtime  # not trained again


def test_bad_arguments_exit_2_with_one_line(tmp_path):
    result = subprocess.run([sys.executable, "-m", "league.reproduce", "--env-steps", "0", "--out", str(tmp_path / "o")],
                            capture_output=True, text=True)
    assert result.returncode == 2 and "every budget must be at least 1" in result.stderr
    assert not (tmp_path / "o").exists()
