"""``league.reproduce``: budgets and variants become valid configs; a restart reuses finished runs."""

import subprocess
import sys

import pytest

from league.config import load_config
from league.studies.table_one import Budget, phases_override

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


def reproduce(out, *extra):
    command = [sys.executable, "-m", "league.reproduce", "--seeds", "1", "--methods", "2", "--env-steps", "1500",
               "--evaluation-episodes", "20", "--out", str(out), *TINY, *extra]
    return subprocess.run(command, capture_output=True, text=True)


def test_the_table_from_a_trained_run_and_a_restart_reuses_it(tmp_path):
    """(A killed run resumed: ``tests/studies/test_trials.py``, through the same runner.)"""
    run_dir = tmp_path / "paper" / "env-steps-1500" / "method2-seed0"
    first = reproduce(tmp_path)
    assert first.returncode == 0, first.stdout[-2000:] + first.stderr[-2000:]
    assert f"training paper, 1,500 env steps, method 2, seed 0 -> {run_dir.resolve()}" in first.stdout
    assert "study: 1 of 1 runs done (0 reused)" in first.stdout
    table = (tmp_path / "paper" / "env-steps-1500" / "table1.md").read_text()
    assert "1,500 env steps of training" in table and "| 2 | " in table
    assert (tmp_path / "paper" / "env-steps-1500" / "curves-method2" / "curves.png").exists()
    assert "iteration" in (tmp_path / "logs" / "paper-env-steps-1500-method2-seed0.log").read_text()

    db_mtime = (run_dir / "league.db").stat().st_mtime
    again = reproduce(tmp_path)
    assert again.returncode == 0 and again.stdout.startswith("study: 1 of 1 runs done (1 reused)")
    assert "training paper" not in again.stdout
    assert (run_dir / "league.db").stat().st_mtime == db_mtime  # not trained again


def test_bad_arguments_exit_2_with_one_line(tmp_path):
    result = subprocess.run([sys.executable, "-m", "league.reproduce", "--env-steps", "0", "--out", str(tmp_path / "o")],
                            capture_output=True, text=True)
    assert result.returncode == 2 and "every budget must be at least 1" in result.stderr
    assert not (tmp_path / "o").exists()
