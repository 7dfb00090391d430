"""The meta-game solver against games with known solutions and the LP's optimality conditions."""

import numpy as np
import pytest

from league.analysis.nash import (
    FACE_TOLERANCE, SUPPORT_THRESHOLD, format_meta_game, meta_game, solve_zero_sum, weight_range, weight_group,
)
from league.core.players import Player

# HiGHS solves to feasibility tolerances of 1e-7, and weights below SUPPORT_THRESHOLD (1e-6)
# are dropped and the rest renormalised; with entries in [0, 1] and at most 7 strategies a
# side, an expected payoff moves by at most 7 * 1e-6 from that. 1e-5 covers both.
TOL = 1e-5
# A Nash range's ends: the optimal face is widened by FACE_TOLERANCE (1e-6), which lets a strategy
# that loses g per unit of weight below the value take up to 1e-6 / g; g >= 0.05 in these games.
RANGE_TOL = FACE_TOLERANCE / 0.05


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
    attackers = [Player("attacker", "snapshot", 1, 2, id=1), Player("attacker", "scripted", 0, scripted_attacker="pure_pursuit", id=2)]
    teams = [Player("team", "snapshot", 1, id=3), Player("team", "snapshot", 2, id=4)]
    payoff = {(1, 3): (10, 10), (1, 4): (0, 10), (2, 3): (0, 10), (2, 4): (10, 10)}
    meta = meta_game(attackers, teams, payoff)
    assert meta.equilibrium.value == pytest.approx(0.5, abs=TOL)
    assert meta.ratings() == pytest.approx({1: 0.5, 2: 0.5, 3: 0.5, 4: 0.5}, abs=TOL)
    text = format_meta_game(meta)
    assert "value 0.500" in text and "attacker-m2-v1" in text and "team-v2" in text
    del payoff[(2, 4)]
    assert meta_game(attackers, teams, payoff) is None


# ---------------------------------------------------------------- Nash ranges
def test_a_tie_between_a_mixture_and_a_pure_strategy_leaves_the_whole_weight_open():
    # Rows 1 and 2 mixed evenly and row 3 alone both hold the value 0.5; the LP returns the former.
    payoff = [[0.9, 0.1], [0.1, 0.9], [0.5, 0.5]]
    assert solve_zero_sum(payoff).row_mixture @ [1, 1, 0] == pytest.approx(1.0)
    assert weight_range(payoff, "row", [0, 1]) == pytest.approx((0.0, 1.0), abs=RANGE_TOL)
    assert weight_range(payoff, "row", [2]) == pytest.approx((0.0, 1.0), abs=RANGE_TOL)
    # The teams' equilibrium is unique: (0.5, 0.5) is the only mixture that holds row 1 and row 2 to 0.5.
    assert weight_range(payoff, "column", [0]) == pytest.approx((0.5, 0.5), abs=RANGE_TOL)


def test_a_unique_equilibrium_has_a_point_range_at_the_lp_weight():
    payoff = [[0.7, 0.3, 0.9], [0.2, 0.6, 0.8], [0.6, 0.2, 0.85]]  # the dominated-strategies game above
    eq = solve_zero_sum(payoff)
    for side, mixture in (("row", eq.row_mixture), ("column", eq.column_mixture)):
        for members in ([0], [1], [2], [0, 2], [0, 1, 2]):
            low, high = weight_range(payoff, side, members)
            assert low == pytest.approx(mixture[members].sum(), abs=RANGE_TOL), (side, members)
            assert high == pytest.approx(mixture[members].sum(), abs=RANGE_TOL), (side, members)


@pytest.mark.parametrize("seed", range(3))
def test_a_random_game_with_a_duplicated_row_splits_it_freely_and_holds_the_lp_weight_in_range(seed):
    payoff = np.random.default_rng(seed).uniform(size=(4, 5))
    payoff = np.vstack([payoff, payoff[np.argmax(solve_zero_sum(payoff).row_mixture)]])  # a copy of a support row
    eq = solve_zero_sum(payoff)
    copies = [int(np.argmax(eq.row_mixture[:4])), 4]
    pair = eq.row_mixture[copies].sum()
    loose = 1e-3  # a random game's least loss per unit of weight off the face, g, can be 0.01: 1e-6 / g = 1e-4
    assert weight_range(payoff, "row", copies) == pytest.approx((pair, pair), abs=loose)
    for k in copies:
        assert weight_range(payoff, "row", [k]) == pytest.approx((0.0, pair), abs=loose)
    for k in range(4):
        low, high = weight_range(payoff, "row", [k])
        assert low - 1e-9 <= eq.row_mixture[k] <= high + 1e-9


def test_duplicated_columns_split_their_weight_anywhere():
    # A saddle point on column 1 or its copy, column 2: any split of the team's weight between them is optimal.
    saddle = [[0.4, 0.4, 0.7], [0.2, 0.2, 0.9]]
    assert weight_range(saddle, "column", [0]) == pytest.approx((0.0, 1.0), abs=RANGE_TOL)
    assert weight_range(saddle, "column", [1]) == pytest.approx((0.0, 1.0), abs=RANGE_TOL)
    assert weight_range(saddle, "column", [0, 1]) == pytest.approx((1.0, 1.0), abs=RANGE_TOL)
    assert weight_range(saddle, "column", [2]) == pytest.approx((0.0, 0.0), abs=RANGE_TOL)
    # Matching pennies with the second column twice: the copies share its 0.5 in any proportion.
    pennies = [[1.0, 0.0, 0.0], [0.0, 1.0, 1.0]]
    assert weight_range(pennies, "column", [1]) == pytest.approx((0.0, 0.5), abs=RANGE_TOL)
    assert weight_range(pennies, "column", [2]) == pytest.approx((0.0, 0.5), abs=RANGE_TOL)
    assert weight_range(pennies, "column", [1, 2]) == pytest.approx((0.5, 0.5), abs=RANGE_TOL)


def test_the_meta_game_reports_each_sides_groups_with_their_vertex_weight_and_range():
    attackers = [
        Player("attacker", "snapshot", 1, 2, id=1), Player("attacker", "snapshot", 2, 2, id=2),
        Player("attacker", "scripted", 0, scripted_attacker="lead_intercept", id=3),
        Player("attacker", "exploiter_snapshot", 1, 2, id=4),
    ]
    teams = [Player("team", "snapshot", 0, id=5), Player("team", "snapshot", 1, id=6)]
    assert [weight_group(p) for p in attackers + teams] == [
        "learners", "learners", "scripted_and_v0", "exploiters", "scripted_and_v0", "learners"]
    # The tie game above; the exploiter wins less against both teams, so no optimal mixture plays it.
    rates = [[0.9, 0.1], [0.1, 0.9], [0.5, 0.5], [0.4, 0.4]]
    payoff = {(a.id, t.id): (round(100 * rates[i][j]), 100)
              for i, a in enumerate(attackers) for j, t in enumerate(teams)}
    meta = meta_game(attackers, teams, payoff)
    groups = {(g["side"], g["group"]): g for g in meta.as_json()["groups"]}
    assert set(groups) == {(side, group) for side in ("attacker", "team")
                           for group in ("learners", "exploiters", "oracles", "scripted_and_v0")}
    learners = groups[("attacker", "learners")]
    assert learners["players"] == ["attacker-m2-v1", "attacker-m2-v2"]
    assert learners["vertex_weight"] == pytest.approx(1.0, abs=TOL)
    assert learners["range"] == pytest.approx([0.0, 1.0], abs=RANGE_TOL)
    assert groups[("attacker", "scripted_and_v0")]["range"] == pytest.approx([0.0, 1.0], abs=RANGE_TOL)
    assert groups[("attacker", "exploiters")]["range"] == pytest.approx([0.0, 0.0], abs=RANGE_TOL)
    assert groups[("team", "learners")]["players"] == ["team-v1"]
    assert groups[("team", "learners")]["range"] == pytest.approx([0.5, 0.5], abs=RANGE_TOL)
    assert groups[("team", "exploiters")] == {
        "side": "team", "group": "exploiters", "players": [], "vertex_weight": 0.0, "range": [0.0, 0.0]}
    text = format_meta_game(meta)
    assert "| attacker | trained learners' snapshots (v1 on) | 2 | 1.000 | 0.000 to 1.000 |" in text
    assert "one optimal vertex" in text
    assert "| team | exploiters' snapshots |" not in text  # an empty group has no row
