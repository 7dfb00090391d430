"""Every branch of the paper's reward equations, with hand-computed values."""

import numpy as np
import pytest

from envs.config import GameConfig
from envs.core import BatchedGame
from envs.rewards import attacker_method1, attacker_method2, attacker_method3, team_rewards

GAMMA = np.array([10.0])


@pytest.mark.parametrize(
    "d_at_prev, d_at, d_ad_prev, d_ad, expected",
    [
        (1.0, 0.8, 1.0, 1.0, 4.5),  # closing on T, not on D: 45 / Gamma
        (1.0, 0.8, 1.0, 0.8, 3.0),  # closing on both: 30 / Gamma
        (1.0, 0.95, 1.0, 0.95, 0.3),  # neither: 3 / Gamma
        (1.0, 0.95, 1.0, 0.8, 0.0),  # closing on D only: 0
        (1.0, 1.2, 1.0, 1.3, 0.3),  # moving away from both counts as "neither"
    ],
)
def test_method1_branches(d_at_prev, d_at, d_ad_prev, d_ad, expected):
    args = [np.array([x]) for x in (d_at_prev, d_at, d_ad_prev, d_ad)]
    assert attacker_method1(*args, GAMMA)[0] == pytest.approx(expected)


@pytest.mark.parametrize(
    "offset, expected",
    [
        (0.0, 6.0),  # x = 0: max(2 - 0, 1) * 30 / 10
        (0.25, 4.5),  # x = 0.5: 1.5 * 3
        (0.5, 3.0),  # x = 1: still the first case, max(1, 1)
        (0.75, 1.5),  # x = 1.5: max(0.5, 0) * 3
        (1.0, 0.0),  # x = 2: max(0, 0)
        (1.25, -4.5),  # x = 2.5: max(-1.5, -2) * 3
        (2.0, -6.0),  # x = 4: floored at -2
    ],
)
def test_method2_branches(offset, expected):
    assert attacker_method2(np.array([offset]), 0.5, GAMMA)[0] == pytest.approx(expected)


@pytest.mark.parametrize(
    "lambda_prev, lambda_now, count, expected_reward, expected_count",
    [
        (1.0, 0.8, 0, 1.4, 0),  # progress 0.2: min(2 * 0.2 + 1, 2) * 10 / 10
        (1.0, 0.4, 3, 2.0, 3),  # progress 0.6: capped at 2; counter untouched
        (1.0, 0.98, 0, 0.04 - 1.08, 1),  # progress below 0.05: -max(-0.04, -1) - 1.08 ** 1
        (1.0, 1.7, 2, 1.0 - 1.08**3, 3),  # moving away 0.7: -max(-1.4, -1) = 1, minus 1.08 ** 3
    ],
)
def test_method3_branches_and_overchase_counter(lambda_prev, lambda_now, count, expected_reward, expected_count):
    reward, new_count = attacker_method3(
        np.array([lambda_prev]), np.array([lambda_now]), np.array([count]), 1.08, GAMMA
    )
    assert reward[0] == pytest.approx(expected_reward)
    assert new_count[0] == expected_count


def test_team_rewards_are_negated_costs():
    r_t, r_d = team_rewards(np.array([2.0]), np.array([1.0]), np.array([0.5]), 0.6, 0.4, GAMMA)
    assert r_t[0] == pytest.approx(-(0.6 * 2.0 - 0.4 * 1.0) / 10)
    assert r_d[0] == pytest.approx(-0.05)


def test_team_sign_convention_rewards_progress():
    near, far = np.array([1.0]), np.array([2.0])
    # T is paid more nearer the terminal and farther from A; D is paid more nearer A.
    assert team_rewards(near, far, far, 0.6, 0.4, GAMMA)[0] > team_rewards(far, far, far, 0.6, 0.4, GAMMA)[0]
    assert team_rewards(far, far, far, 0.6, 0.4, GAMMA)[0] > team_rewards(far, near, far, 0.6, 0.4, GAMMA)[0]
    assert team_rewards(far, far, near, 0.6, 0.4, GAMMA)[1] > team_rewards(far, far, far, 0.6, 0.4, GAMMA)[1]


def one_step(attacker_reward, attacker_yaw):
    game = BatchedGame(GameConfig(attacker_reward=attacker_reward), 1)
    game.reset(positions=np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 5.0, 0.0]]]))
    game.headings[0, 0, 0] = attacker_yaw
    assert game.time_limit[0] == 16  # ceil(2 * 1 / 0.13)
    return game, game.step(np.zeros((1, 3, 2)))


def test_core_method2_pays_full_reward_on_the_reference_direction():
    # T flies +x at v_T; its lead-intercept point lies straight ahead of A on the x axis.
    _, result = one_step(2, 0.0)
    assert result.rewards[0, 0] == pytest.approx(2 * 30 / 16)


def test_core_method3_counts_overchasing_when_flying_away():
    # lambda = r / (v_A - v_T) + v_T * r / (v_A - v_T) on the x axis: 3.6 before, 4.716 after.
    game, result = one_step(3, np.pi)
    assert game.collision_distance[0] == pytest.approx(4.716)
    assert game.overchase_count[0] == 1
    assert result.rewards[0, 0] == pytest.approx(10 / 16 - 1.08)


def test_core_method1_uses_distances_of_the_step():
    _, result = one_step(1, 0.0)
    # A-T shrinks by 0.18 - 0.13 = 0.05 (<= 0.1) and A-D does not shrink by 0.1: 3 / Gamma.
    assert result.rewards[0, 0] == pytest.approx(3 / 16)


@pytest.mark.parametrize("terminal_reward", [0.0, 1.0])
def test_all_attacker_methods_are_reported_and_the_configured_one_is_paid(terminal_reward):
    positions = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 5.0, 0.0]]])
    by_method = []
    for method in (1, 2, 3):
        game = BatchedGame(GameConfig(attacker_reward=method, terminal_reward=terminal_reward), 1)
        game.reset(positions=positions)
        result = game.step(np.zeros((1, 3, 2)))
        assert result.rewards[0, 0] == result.attacker_rewards[0, method - 1]
        by_method.append(result.attacker_rewards[0])
    np.testing.assert_array_equal(by_method[0], by_method[1])
    np.testing.assert_array_equal(by_method[0], by_method[2])
    assert by_method[0][1] == pytest.approx(2 * 30 / 16)
