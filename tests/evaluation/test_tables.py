"""The per-method table: a column pooling k teams on the same n fixed starts gets the
interval of n games, not of k * n independent ones."""

import re

import numpy as np
import pytest

from envs.agents import Outcome
from envs.match import GameResults
from league.analysis.statistics import wilson_interval
from league.core.players import Player
from league.evaluation.engine import PairEvaluation
from league.evaluation.tables import method_table

STARTS = 200


def pair(attacker: Player, team: Player, wins: int) -> PairEvaluation:
    """``STARTS`` games of which the first ``wins`` the attacker won."""
    outcome = np.where(np.arange(STARTS) < wins, Outcome.CAPTURED, Outcome.TERMINAL_REACHED)
    return PairEvaluation(attacker, team, GameResults(outcome, np.ones(STARTS, int), np.zeros((STARTS, 3))))


def cells(table: str) -> dict[str, tuple[float, float, float]]:
    header, _, row = table.splitlines()[:3]
    names = [c.strip() for c in header.strip("|").split("|")][2:]
    values = [c.strip() for c in row.strip("|").split("|")][2:]
    parsed = [tuple(map(float, re.fullmatch(r"([\d.]+) \[([\d.]+), ([\d.]+)\]", v).groups())) for v in values]
    return dict(zip(names, parsed))


def test_the_league_pool_interval_counts_the_distinct_starts():
    attacker = Player("attacker", "snapshot", 1, reward_method=2, id=1)
    teams = [
        Player("team", "scripted", 0, scripted_targeter="straight", scripted_defender="pure_pursuit", id=2),
        Player("team", "scripted", 0, scripted_targeter="avoid_attacker", scripted_defender="pure_pursuit", id=3),
        Player("team", "snapshot", 1, id=4),
    ]
    wins = (60, 100, 140)  # k = 3 teams on the same 200 starts: pooled rate 300 / 600 = 0.5
    table = cells(method_table([pair(attacker, t, w) for t, w in zip(teams, wins)]))
    rate, low, high = table["league pool"]
    assert rate == pytest.approx(0.5)
    assert (low, high) == pytest.approx(wilson_interval(100, STARTS), abs=1e-3)  # the width of 200 games (0.137) ...
    naive = wilson_interval(sum(wins), len(teams) * STARTS)
    assert high - low > (naive[1] - naive[0]) + 0.05  # ... not of 600 (0.080)
    # a column of one team: its own games, as before
    assert table[teams[0].name][1:] == pytest.approx(wilson_interval(60, STARTS), abs=1e-3)
