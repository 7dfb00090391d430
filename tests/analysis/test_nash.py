"""The meta-game solver against games with known solutions and the LP's optimality conditions."""

import numpy as np
import pytest

from league.analysis.nash import SUPPORT_THRESHOLD, format_meta_game, meta_game, solve_zero_sum
from league.core.players import Player

# HiGHS solves to feasibility tolerances of 1e-7, and weights below SUPPORT_THRESHOLD (1e-6)
# are dropped and the rest renormalised; with entries in [0, 1] and at most 7 strategies a
# side, an expected payoff moves by at most 7 * 1e-6 from that. 1e-5 covers both.
TOL = 1e-5


def test_matching_pennies_in_win_rate_form():
    eq = solve_zero_sum([[1.0, 0.0], [0.0, 1.0]])
    assert eq.value == pytest.approx(0.5, abs=TOL)
    np.testing.assert_allclose(eq.row_mixture, [0.5, 0.5], atol=TOL)
    np.testing.assert_allclose(eq.column_mixture, [0.5, 0.5], atol=TOL)
    np.testing.assert_allclose(eq.row_ratings, [0.5, 0.5], atol=TOL)
    np.testing.assert_allclose(eq.column_ratings, [0.5, 0.5], atol=TOL)


def test_rock_paper_scissors():
    # Win 1, lose 0, draw 0.5 for the row player.
    eq = solve_zero_sum([[0.5, 0.0, 1.0], [1.0, 0.5, 0.0], [0.0, 1.0, 0.5]])
    assert eq.value == pytest.approx(0.5, abs=TOL)
    np.testing.assert_allclose(eq.row_mixture, [1 / 3] * 3, atol=TOL)
    np.testing.assert_allclose(eq.column_mixture, [1 / 3] * 3, atol=TOL)


def test_dominated_strategies_get_no_weight():
    # Row 3 is strictly dominated by row 1, column 3 (the team's loss) by column 2 for the team.
    payoff = [[0.7, 0.3, 0.9], [0.2, 0.6, 0.8], [0.6, 0.2, 0.85]]
    eq = solve_zero_sum(payoff)
    assert eq.row_mixture[2] == 0.0
    assert eq.column_mixture[2] == 0.0
    # The 2x2 game left: rows (0.7, 0.3) and (0.2, 0.6); x = 0.4 / 0.8, value 0.45.
    np.testing.assert_allclose(eq.row_mixture, [0.5, 0.5, 0.0], atol=TOL)
    np.testing.assert_allclose(eq.column_mixture, [0.375, 0.625, 0.0], atol=TOL)
    assert eq.value == pytest.approx(0.45, abs=TOL)
    assert eq.row_ratings[2] == pytest.approx(0.6 * 0.375 + 0.2 * 0.625, abs=TOL)  # 0.35: below the value


def test_pure_saddle_point():
    # (row 2, column 1) is the minimum of its row and the maximum of its column.
    eq = solve_zero_sum([[0.3, 0.6, 0.7], [0.4, 0.5, 0.45], [0.1, 0.9, 0.2]])
    np.testing.assert_allclose(eq.row_mixture, [0, 1, 0], atol=TOL)
    np.testing.assert_allclose(eq.column_mixture, [1, 0, 0], atol=TOL)
    assert eq.value == pytest.approx(0.4, abs=TOL)


@pytest.mark.parametrize("seed", range(5))
def test_random_non_square_game_meets_the_optimality_conditions(seed):
    payoff = np.random.default_rng(seed).uniform(size=(5, 7))
    eq = solve_zero_sum(payoff)
    for mixture in (eq.row_mixture, eq.column_mixture):
        assert mixture.min() >= 0 and mixture.sum() == pytest.approx(1.0, abs=1e-12)
        assert not np.any((mixture > 0) & (mixture < SUPPORT_THRESHOLD))
    # No attacker beats the value against the team mixture, no team beats it against the attacker mixture...
    assert (payoff @ eq.column_mixture).max() <= eq.value + TOL
    assert (eq.row_mixture @ payoff).min() >= eq.value - TOL
    # ...and the mixtures' own strategies reach it (complementary slackness).
    np.testing.assert_allclose((payoff @ eq.column_mixture)[eq.row_mixture > 0], eq.value, atol=TOL)
    np.testing.assert_allclose((eq.row_mixture @ payoff)[eq.column_mixture > 0], eq.value, atol=TOL)
    assert eq.row_ratings.max() == pytest.approx(eq.value, abs=TOL)
    assert eq.column_ratings.max() == pytest.approx(1 - eq.value, abs=TOL)


def test_bad_matrices_are_refused():
    with pytest.raises(ValueError, match="NaN"):
        solve_zero_sum([[0.5, np.nan]])
    with pytest.raises(ValueError, match="2-D"):
        solve_zero_sum(np.zeros((0, 3)))


def test_league_meta_game_names_players_and_needs_every_pair():
    attackers = [Player(1, "attacker", "snapshot", 1, 2), Player(2, "attacker", "scripted", 0, scripted_attacker="pure_pursuit")]
    teams = [Player(3, "team", "snapshot", 1), Player(4, "team", "snapshot", 2)]
    payoff = {(1, 3): (10, 10), (1, 4): (0, 10), (2, 3): (0, 10), (2, 4): (10, 10)}
    meta = meta_game(attackers, teams, payoff)
    assert meta.equilibrium.value == pytest.approx(0.5, abs=TOL)
    assert meta.ratings() == pytest.approx({1: 0.5, 2: 0.5, 3: 0.5, 4: 0.5}, abs=TOL)
    text = format_meta_game(meta)
    assert "value 0.500" in text and "attacker-m2-v1" in text and "team-v2" in text
    del payoff[(2, 4)]
    assert meta_game(attackers, teams, payoff) is None
