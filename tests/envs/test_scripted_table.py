"""The scripted players' table, pinned: every scripted attacker against every scripted team on
the fixed evaluation games of every scenario set, attacker win counts exact.

A change to a scripted player, the kinematics, the rules or a scenario set that moves any
count fails here (two constants of ``envs/scripted.py`` once moved lead intercept against
the paper's team from 0.384 to 0.345 with every other test passing). When the change is
meant, regenerate the table and say in the commit which rows moved and why:

    python tests/envs/test_scripted_table.py --write

The counts are numpy float64 arithmetic (sin, cos, arctan2, arcsin included) and were the
same with numpy's AVX-512 kernels and with them turned off
(``NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR"``, numpy's AVX2 ones).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from envs.config import GameConfig
from envs.match import play, scripted_players
from envs.scenarios import SCENARIO_SETS, evaluation_scenarios
from envs.scripted import PLAYERS

TABLE = Path(__file__).with_name("scripted_table.json")
# Fixed games per pair: the whole table plays in about 45 s of one core.
EPISODES = {"default": 1000, "defender_close": 250, "attacker_far": 250, "long_flight": 250}


def attacker_wins(scenario: str) -> dict[str, int]:
    """``"ATTACKER vs TARGETER+DEFENDER"``: the attacker's wins on the set's first ``EPISODES`` fixed games."""
    config = GameConfig(scenario=scenario)
    positions = evaluation_scenarios(scenario, EPISODES[scenario])
    return {
        f"{attacker} vs {targeter}+{defender}": int(play(config, scripted_players(attacker, targeter, defender), positions).attacker_wins.sum())
        for attacker in PLAYERS["attacker"]
        for targeter in PLAYERS["targeter"]
        for defender in PLAYERS["defender"]
    }


def test_every_scenario_set_and_scripted_player_is_pinned():
    pinned = json.loads(TABLE.read_text())
    assert pinned["episodes"] == EPISODES and set(EPISODES) == set(SCENARIO_SETS)
    for wins in pinned["wins"].values():
        assert len(wins) == len(PLAYERS["attacker"]) * len(PLAYERS["targeter"]) * len(PLAYERS["defender"])


@pytest.mark.parametrize("scenario", sorted(SCENARIO_SETS))
def test_scripted_attacker_wins_are_the_pinned_counts(scenario):
    pinned = json.loads(TABLE.read_text())["wins"][scenario]
    played = attacker_wins(scenario)
    moved = {pair: f"{pinned.get(pair)} -> {n}" for pair, n in played.items() if pinned.get(pair) != n}
    assert not moved, f"{scenario!r}, {EPISODES[scenario]} games per pair: attacker wins moved: {moved}"


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit(f"usage: python {Path(__file__).name} --write   (regenerates {TABLE.name})")
    table = {"episodes": EPISODES, "wins": {scenario: attacker_wins(scenario) for scenario in EPISODES}}
    TABLE.write_text(json.dumps(table, indent=1) + "\n")
    print(f"wrote {TABLE}")
