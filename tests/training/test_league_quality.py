"""bench/league_quality.py's arms: valid configs that give each side the same env-step budget."""

import argparse
import importlib.util
from pathlib import Path

import pytest

from league.config import load_config

SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "league_quality.py"


@pytest.fixture(scope="module")
def league_quality():
    spec = importlib.util.spec_from_file_location("league_quality", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def side_budgets(run) -> dict[str, int]:
    """Env steps each side's learner is given (a self-play phase ends on its learner's steps)."""
    league = run.league
    if league.mode == "protocol":
        budgets = {"attacker": 0, "team": 0}
        for phase in league.phases:
            budgets[phase.learner] += phase.env_steps
        return budgets
    per_side = league.selfplay_phases // 2 * league.phase_env_steps
    return {"attacker": per_side, "team": per_side}


def test_every_arm_gives_both_sides_the_same_total(league_quality):
    args = argparse.Namespace(terminal_reward=30.0, episodes=100, phases=4, phase_env_steps=50_000)
    for arm in league_quality.ARMS:
        run = load_config("selfplay_league", league_quality.arm_overrides(arm, args, 1))
        assert (run.game.attacker_reward, run.game.terminal_reward, run.seed) == (2, 30.0, 1)
        assert run.league.attacker_reward_methods == [2]
        budgets = side_budgets(run)
        # with exploiters the learner gets half: its exploiter samples about as much again
        expected = 50_000 if arm == "league-exploiters" else 100_000
        assert budgets == {"attacker": expected, "team": expected}, arm
        assert run.league.exploiters == (["attacker", "team"] if arm == "league-exploiters" else [])
        assert run.league.pfsp == {"league-variance": "variance", "league-psro": "nash"}.get(arm, "squared"), arm
        if run.league.mode == "selfplay":  # phases end on their budget, never on a win rate
            assert run.league.min_phase_episodes > 10**6
    naive = load_config("selfplay_league", league_quality.arm_overrides("naive", args, 1)).league.phases
    assert [p.opponents for p in naive] == ["scripted", "latest", "latest", "latest"]


def test_an_arms_training_seeds_differ_only_in_their_seed(league_quality):
    args = argparse.Namespace(terminal_reward=30.0, episodes=100, phases=4, phase_env_steps=50_000)
    for arm in league_quality.ARMS:
        runs = [load_config("selfplay_league", league_quality.arm_overrides(arm, args, seed)).model_dump() for seed in (0, 1, 2)]
        assert [run.pop("seed") for run in runs] == [0, 1, 2], arm
        assert runs[0] == runs[1] == runs[2], arm


def test_a_teams_best_response_to_an_attacker_gets_its_own_budget(league_quality):
    from league.core.players import Player

    attacker = Player(id=1, side="attacker", kind="snapshot", version=3, reward_method=2)
    team = Player(id=2, side="team", kind="snapshot", version=3)
    args = argparse.Namespace(br_env_steps=100, team_br_env_steps=300)
    assert (league_quality.br_budget(attacker, args), league_quality.br_budget(team, args)) == (300, 100)
