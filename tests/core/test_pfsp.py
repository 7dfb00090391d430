"""Prioritised fictitious self-play (``league.core.pfsp``): the weightings and the scripted share."""

import numpy as np
import pytest

from league.core.pfsp import pfsp_probabilities, with_scripted_share


def test_a_scripted_share_holds_that_much_of_the_mass_for_the_scripted_players_weighted_by_pfsp():
    x = [0.9, 0.5, 0.1]  # the first two scripted
    p = pfsp_probabilities(x, "squared")
    shared = with_scripted_share(x, [True, True, False], 0.5, "squared")
    np.testing.assert_allclose(shared, 0.5 * p + 0.5 * np.array([0.01, 0.25, 0.0]) / 0.26)
    assert abs(shared.sum() - 1) < 1e-12  # float64 sums of three terms
    np.testing.assert_array_equal(with_scripted_share(x, [False] * 3, 0.5, "squared"), p)  # none scripted: PFSP alone
    np.testing.assert_array_equal(with_scripted_share(x, [True, True, False], 0.0, "squared"), p)


def test_a_uniform_scripted_share_still_meets_a_scripted_player_the_learner_always_beats():
    x = [1.0, 0.5, 0.1]  # the first two scripted; squared gives the first no games
    assert with_scripted_share(x, [True, True, False], 0.5, "squared")[0] == 0.0
    shared = with_scripted_share(x, [True, True, False], 0.5, "squared", scripted_weighting="uniform")
    np.testing.assert_allclose(shared, 0.5 * pfsp_probabilities(x, "squared") + 0.5 * np.array([0.5, 0.5, 0.0]))


def test_the_nash_weighting_is_the_given_mixture_whatever_the_win_rates():
    x = [0.9, 0.5, 0.1]
    np.testing.assert_allclose(pfsp_probabilities(x, "nash", [0.2, 0.0, 0.6]), [0.25, 0.0, 0.75])
    np.testing.assert_allclose(pfsp_probabilities(x, "nash", [0.0, 0.0, 0.0]), [1 / 3] * 3)  # all zero: uniform
    # the scripted share spreads over the scripted candidates by their Nash weights
    shared = with_scripted_share(x, [True, True, False], 0.5, "nash", [0.2, 0.0, 0.6])
    np.testing.assert_allclose(shared, 0.5 * np.array([0.25, 0.0, 0.75]) + 0.5 * np.array([1.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="Nash weight"):
        pfsp_probabilities(x, "nash")


def test_pfsp_weightings():
    np.testing.assert_allclose(pfsp_probabilities([0.0, 0.5, 1.0], "squared"), [0.8, 0.2, 0.0])
    np.testing.assert_allclose(pfsp_probabilities([0.5, 0.9], "variance"), [0.25 / 0.34, 0.09 / 0.34])
    np.testing.assert_allclose(pfsp_probabilities([0.2, 0.9], "uniform"), [0.5, 0.5])
    np.testing.assert_allclose(pfsp_probabilities([1.0, 1.0], "squared"), [0.5, 0.5])  # all zero: uniform
    with pytest.raises(ValueError):
        pfsp_probabilities([], "squared")
