"""Evaluation workers, the evaluate and report command lines."""

import numpy as np
import pytest
import ray

from envs.config import GameConfig
from envs.match import play, scripted_players
from envs.scenarios import evaluation_scenarios
from league.evaluate import main as evaluate_main
from league.evaluation import evaluate_pairs
from league.players import Player
from league.report import main as report_main

ATTACKER = Player(id=1, side="attacker", kind="scripted", version=0, scripted_attacker="proportional_navigation")
TEAM = Player(id=2, side="team", kind="scripted", version=0, scripted_targeter="straight", scripted_defender="bisector_intercept")


@pytest.fixture(scope="module")
def ray_instance():
    ray.init(address="local", num_cpus=2, include_dashboard=False)  # a private instance, whatever else runs
    yield
    ray.shutdown()


def test_workers_give_the_numbers_of_a_plain_loop(ray_instance, tmp_path):
    game = GameConfig()
    [by_workers] = evaluate_pairs(game, tmp_path, [(ATTACKER, TEAM)], 301, workers=3)
    plain = play(game, scripted_players("proportional_navigation", "straight", "bisector_intercept"),
                 evaluation_scenarios("default", 301))
    np.testing.assert_array_equal(by_workers.result.outcome, plain.outcome)
    np.testing.assert_array_equal(by_workers.result.steps, plain.steps)
    np.testing.assert_allclose(by_workers.result.returns, plain.returns)
    assert by_workers.games == 301


def test_evaluation_is_deterministic_for_a_fixed_set(tmp_path):
    game = GameConfig()
    first, second = (evaluate_pairs(game, tmp_path, [(ATTACKER, TEAM)], 200)[0] for _ in range(2))
    np.testing.assert_array_equal(first.result.outcome, second.result.outcome)
    assert first.attacker_wins == second.attacker_wins


def test_evaluate_cli_prints_pairs_and_the_method_table(tiny_run, capsys):
    assert evaluate_main(["--run-dir", str(tiny_run), "--episodes", "30", "--workers", "0"]) == 0
    out = capsys.readouterr().out
    assert "| attacker-m2-v1 | team-v1 | 30 |" in out
    assert "| reward method | attacker |" in out and "| 2 | attacker-m2-v1 |" in out
    assert evaluate_main(["--run-dir", str(tiny_run), "--players", "nobody"]) == 2


def test_training_wrote_evaluations_every_k_iterations(tiny_run):
    import sqlite3

    with sqlite3.connect(tiny_run / "league.db") as db:
        iterations = [row[0] for row in db.execute("SELECT DISTINCT iteration FROM matches WHERE source = 'evaluation'")]
    assert 2 in iterations and len(iterations) >= 2


def test_report_holds_the_expected_files(tiny_run):
    assert report_main(["--run-dir", str(tiny_run)]) == 0
    report = tiny_run / "report"
    text = (report / "report.md").read_text()
    assert "Table 1 analogue" in text and "| 2 | attacker-m2-v1 |" in text and "0.6253" in text
    for name in ("payoff.png", "ratings.png", "win_rates.png", "returns.png", "curves.png"):
        assert (report / name).read_bytes()[:4] == b"\x89PNG"
        assert f"]({name})" in text
    assert list(report.glob("trajectory_attacker_*.png")) and list(report.glob("trajectory_team_*.png"))
    page = (report / "index.html").read_text()
    assert "Table 1 analogue" in page and "attacker-m2-v1" in page
    assert "<script src" not in page and "<link" not in page  # self-contained: opens offline
