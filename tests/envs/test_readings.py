"""The paper's open readings as options, each against a hand computation (see ``GameConfig``)."""

from fractions import Fraction

import numpy as np
import pytest
from pydantic import ValidationError

from envs.config import GameConfig
from envs.core import BatchedGame, time_limit_steps
from envs.rewards import attacker_method3

GAMMA = np.array([10.0])


def test_defaults_keep_the_printed_readings():
    config = GameConfig()
    assert (config.method2_direction, config.method3_variant, config.axis_length) == ("chord", "as_printed", 0.1)


@pytest.mark.parametrize(
    "overrides, key",
    [({"method2_direction": "aim"}, "method2_direction"), ({"method3_variant": "fixed"}, "method3_variant")],
)
def test_unknown_reading_names_the_key(overrides, key):
    with pytest.raises(ValidationError, match=key):
        GameConfig(**overrides)


def turn_onto_the_reference(method2_direction):
    """A at the origin heading -y turns left by pi/2, onto +x: the reference direction.

    T at (1, 0, 0) flies +x at v_T, so its lead-intercept point lies on the x axis ahead
    of A. Gamma = ceil(2 * 1 / 0.13) = 16.
    """
    game = BatchedGame(GameConfig(attacker_reward=2, method2_direction=method2_direction), 1)
    game.reset(positions=np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 5.0, 0.0]]]))
    game.headings[0, 0, 0] = 1.5 * np.pi
    return game.step(np.array([[[1.0, 0.0], [0.0, 0.0], [0.0, 0.0]]])).rewards[0, 0]


def test_method2_chord_scores_half_the_turn():
    # The chord of a pi/2 arc points pi/4 off the start: x = (pi/4) / (pi/6) = 1.5,
    # the second case of Eq. 8: max(2 - 1.5, 0) * 30 / 16.
    assert turn_onto_the_reference("chord") == pytest.approx(0.5 * 30 / 16, abs=1e-12)


def test_method2_heading_scores_where_the_attacker_points():
    # The heading at the end of the step is the reference direction: x = 0, 2 * 30 / 16.
    # (1e-6: arccos near 1 resolves ~1e-8 rad; x = 1e-8 / (pi/6) moves the reward by ~1e-7.)
    assert turn_onto_the_reference("heading") == pytest.approx(2 * 30 / 16, abs=1e-6)


@pytest.mark.parametrize(
    "lambda_prev, lambda_now, count, expected_reward, expected_count",
    [
        (1.0, 0.8, 0, 1.4, 0),  # progress 0.2: the same as printed, min(2 * 0.2 + 1, 2) * 10 / 10
        (1.0, 0.98, 0, -(0.04 + 1.08), 1),  # progress 0.02 < 0.05: -(min(0.04, 1) + 1.08 ** 1) * 10 / 10
        (1.0, 1.7, 2, -(1.0 + 1.08**3), 3),  # moving away 0.7: -(min(1.4, 1) + 1.08 ** 3) * 10 / 10
    ],
)
def test_method3_corrected_branches(lambda_prev, lambda_now, count, expected_reward, expected_count):
    reward, new_count = attacker_method3(
        np.array([lambda_prev]), np.array([lambda_now]), np.array([count]), 1.08, GAMMA, "corrected"
    )
    assert reward[0] == pytest.approx(expected_reward)
    assert new_count[0] == expected_count


def test_method3_corrected_in_the_core():
    # A flies away from T (the case of tests/envs/test_rewards.py): lambda 3.6 -> 4.716, |dl| = 1.116,
    # so the corrected reward is -(min(2.232, 1) + 1.08 ** 1) * 10 / 16 = -1.3.
    game = BatchedGame(GameConfig(attacker_reward=3, method3_variant="corrected"), 1)
    game.reset(positions=np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 5.0, 0.0]]]))
    game.headings[0, 0, 0] = np.pi
    result = game.step(np.zeros((1, 3, 2)))
    assert result.rewards[0, 0] == pytest.approx(-1.3)
    assert result.attacker_rewards[0, 2] == pytest.approx(-1.3)


def test_gamma_of_an_exact_multiple_is_that_multiple():
    # |T0| = 8.255: 2 * 8.255 / 0.13 = 127 exactly, 127.00000000000001 in floats.
    game = BatchedGame(GameConfig(), 1)
    game.reset(positions=np.array([[[0.0, 5.0, 0.0], [8.255, 0.0, 0.0], [0.0, -5.0, 0.0]]]))
    assert game.time_limit[0] == 127


def test_gamma_is_the_exact_ceiling_of_decimal_starts():
    # |T0| = k / 2000 for k = 1 .. 20000: Gamma = ceil(2 |T0| / 0.13) computed in exact fractions.
    k = np.arange(1, 20_001)
    distance = k / 2000
    expected = [-((-2 * Fraction(int(i), 2000)) // Fraction(13, 100)) for i in k]  # ceil of an exact fraction
    np.testing.assert_array_equal(time_limit_steps(GameConfig(), distance), expected)
