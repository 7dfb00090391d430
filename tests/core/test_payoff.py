"""The payoff table (``league.core.payoff``): who wins each outcome, records and Elo ratings."""

import numpy as np
import pytest

from envs.agents import Outcome
from league.core.payoff import ATTACKER_WINS, OutcomeCount, aggregate, attacker_won, elo_ratings, player_record, record_against, win_rate, wins_of


def test_unplayed_pair_is_even_and_elo_orders_players():
    assert win_rate(0, 0) == 0.5
    ratings = elo_ratings([(1, 2, 80, 100), (3, 2, 20, 100)], [1, 2, 3])
    assert ratings[1] > ratings[2] > ratings[3]
    even = elo_ratings([(1, 2, 50, 100)], [1, 2])
    assert even[1] == pytest.approx(even[2])


def test_who_wins_each_outcome_and_from_which_side():
    assert ATTACKER_WINS == {"captured", "timeout"}
    assert [attacker_won(o.label) for o in Outcome if o != Outcome.RUNNING] == [True, True, False, False]
    # attacker 1 vs team 2: 3 captures, 1 timeout, 6 times T reached the terminal
    rows = [OutcomeCount(*row) for row in
            [(1, 2, "captured", 3), (1, 2, "timeout", 1), (1, 2, "terminal_reached", 6), (4, 2, "attacker_intercepted", 5)]]
    assert [row.wins("team") for row in rows] == [0, 0, 6, 5]
    table = aggregate(rows)
    assert table == {(1, 2): (4, 10), (4, 2): (0, 5)}
    assert record_against(table, "attacker", 1, 2) == (4, 10)
    assert record_against(table, "team", 2, 1) == (6, 10)
    assert record_against(table, "team", 2, 3) == (0, 0)  # never played
    assert player_record(table, "team", 2) == (11, 15)
    assert player_record(table, "attacker", 4) == (0, 5)
    assert wins_of("team", np.array([1, 0, 1]), 1).tolist() == [0, 1, 0]  # single games
