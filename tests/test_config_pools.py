"""The shipped configs that say they train against every scripted player do: every attacker of
``envs.scripted.PLAYERS`` and every targeter with every defender, in the league's pools."""

from pathlib import Path

import pytest

from envs.scripted import PLAYERS
from league.config import load_config

CONFIGS = Path(__file__).resolve().parent.parent / "configs"
CLAIM = "every scripted player"
# The protocol configs and the self-play league; the _paper configs keep the paper's one
# scripted team and attacker, smoke.yaml its budget, cluster.yaml the defaults.
EVERY_SCRIPTED = ["attacker_method1", "attacker_method2", "attacker_method3", "selfplay_league"]


def claims_every_scripted_player(name: str) -> bool:
    return CLAIM in (CONFIGS / f"{name}.yaml").read_text().lower()


def test_the_configs_that_say_every_scripted_player_are_the_listed_ones():
    claiming = sorted(p.stem for p in CONFIGS.glob("*.yaml") if claims_every_scripted_player(p.stem))
    assert claiming == sorted(EVERY_SCRIPTED)


@pytest.mark.parametrize("name", EVERY_SCRIPTED)
def test_the_pools_hold_every_scripted_player(name):
    league = load_config(name).league
    teams = {(team.targeter, team.defender) for team in league.scripted_teams}
    assert sorted(league.scripted_attackers) == sorted(PLAYERS["attacker"])
    assert teams == {(t, d) for t in PLAYERS["targeter"] for d in PLAYERS["defender"]}
    assert len(teams) == len(league.scripted_teams)  # none twice
