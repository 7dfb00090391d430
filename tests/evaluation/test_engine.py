"""Evaluation on the rollout, its workers, the evaluate and report command lines."""

import numpy as np
import pytest
import ray
import torch

from envs.config import GameConfig
from envs.match import play, scripted_players
from envs.scenarios import evaluation_scenarios
from envs.scripted import PLAYERS, ScriptedPlayer
from league.config import load_config
from league.evaluate import main as evaluate_main
from league.evaluation.engine import LearnedAgent, deterministic, evaluate_pair, evaluate_pairs, merge, play_fixed_games
from league.rllib.bridge import learner_spec
from league.rollout.games import ScriptedOnState
from league.core.players import Player
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
    for field in ("outcome", "steps", "returns", "attacker_returns"):
        np.testing.assert_array_equal(getattr(by_workers.result, field), getattr(plain, field))
    assert by_workers.games == 301


def assert_same_games(rollout, plain):
    """Bit for bit: both loops step the same core with the same actions, in the same order."""
    for field in ("outcome", "steps", "returns", "attacker_returns"):
        np.testing.assert_array_equal(getattr(rollout, field), getattr(plain, field), err_msg=field)


@pytest.mark.parametrize("attacker", sorted(PLAYERS["attacker"]))
def test_the_rollout_plays_the_fixed_games_as_the_plain_loop(attacker):
    game, positions = GameConfig(), evaluation_scenarios("default", 300)
    plain = play(game, scripted_players(attacker, "avoid_attacker", "bisector_intercept"), positions)
    rollout = play_fixed_games(game, positions, {
        "attacker": ("a", ScriptedOnState(attacker)),
        "targeter": ("t", ScriptedOnState("avoid_attacker")),
        "defender": ("d", ScriptedOnState("bisector_intercept")),
    })
    assert_same_games(rollout, plain)
    assert len(set(plain.outcome.tolist())) > 1  # games that end in different ways


def test_a_learned_team_plays_as_two_controllers_of_the_plain_loop():
    # The rollout runs the team's module once per step over both agents' observations.
    torch.manual_seed(0)
    module = learner_spec(load_config("smoke"), "team").build().eval()
    game, positions = GameConfig(), evaluation_scenarios("default", 300)
    plain = play(game, {
        "attacker": ScriptedPlayer("attacker", "lead_intercept"),
        "targeter": LearnedAgent(module, "targeter"),
        "defender": LearnedAgent(module, "defender"),
    }, positions)
    act = deterministic(module)

    def act_per_agent(obs):
        # The rollout hands the module T's rows, then D's, in one call; the plain loop one agent
        # at a time. A matmul over 600 rows may take another kernel than over 300 and round
        # otherwise, so the forward pass runs per agent: the same shapes in the same order.
        parts = [act(half) for half in np.split(obs, 2)]
        return np.concatenate([p[0] for p in parts]), {}

    rollout = play_fixed_games(game, positions, {
        "attacker": ("scripted", ScriptedOnState("lead_intercept")),
        "targeter": ("team", act_per_agent), "defender": ("team", act_per_agent),
    })
    assert_same_games(rollout, plain)


def test_evaluation_is_deterministic_for_a_fixed_set(tmp_path):
    # A learned team saved once: every evaluation below loads its own module object from it.
    torch.manual_seed(0)
    learner_spec(load_config("smoke"), "team").build().save_to_path(str(tmp_path / "team-v1"))
    learned = Player(id=3, side="team", kind="learner", version=1, checkpoint="team-v1")
    game = GameConfig()
    counts = {}
    for team in (TEAM, learned):
        [whole] = evaluate_pairs(game, tmp_path, [(ATTACKER, team)], 100)
        # The same games played in two slices, as the evaluation workers play them.
        halves = merge([evaluate_pair(game, ATTACKER, team, 50, tmp_path, start).result for start in (0, 50)])
        assert_same_games(halves, whole.result)
        assert int(halves.attacker_wins.sum()) == whole.attacker_wins
        if team.kind == "learner":  # another module object loaded from the same weights
            again = evaluate_pair(game, ATTACKER, team, 100, tmp_path)
            assert_same_games(again.result, whole.result)
        # Other games (the next 100 of the set) are played otherwise: the games played are those asked for.
        later = evaluate_pair(game, ATTACKER, team, 100, tmp_path, start=100)
        assert not np.array_equal(later.result.steps, whole.result.steps), team.name
        counts[team.name] = whole.result.outcome_counts(), later.result.outcome_counts()
    # The scripted pair's games end in different ways, in other numbers on the other games (the
    # untrained team loses every game: the same counts on any set).
    first, later = counts[TEAM.name]
    assert sum(n > 0 for n in first.values()) > 1 and later != first, counts


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
