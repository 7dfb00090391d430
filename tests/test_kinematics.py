"""The motion model: constant speed, turn limits, straight flight, angle wrapping."""

import math

import numpy as np
import pytest

from envs.config import GameConfig
from envs.core import BatchedGame
from envs.kinematics import heading_vectors, move, turn

V = np.array([0.18, 0.13, 0.18])
L = 0.1
MAX_YAW, MAX_PITCH = math.pi / 2, math.pi / 4


def random_headings(rng, n):
    return np.stack((rng.uniform(0, 2 * np.pi, (n, 3)), rng.uniform(-np.pi / 2, np.pi / 2, (n, 3))), axis=-1)


def angle(u, v):
    return np.arccos(np.clip(np.sum(u * v, axis=-1), -1, 1))


def test_speed_is_constant_along_the_arc():
    rng = np.random.default_rng(0)
    headings = random_headings(rng, 500)
    new_headings = turn(headings, rng.uniform(-2, 2, (500, 3)), rng.uniform(-1, 1, (500, 3)), MAX_YAW, MAX_PITCH, V / L)
    positions = rng.normal(size=(500, 3, 3))
    new_positions = move(positions, headings, new_headings, V)
    turned = angle(heading_vectors(headings), heading_vectors(new_headings))
    chord = np.linalg.norm(new_positions - positions, axis=-1)
    # An arc of length v turning by alpha has chord 2 (v / alpha) sin(alpha / 2).
    expected = np.where(turned > 1e-9, 2 * (V / np.maximum(turned, 1e-12)) * np.sin(turned / 2), V)
    np.testing.assert_allclose(chord, expected, rtol=1e-9, atol=1e-12)
    assert np.all(chord <= V + 1e-12)


def test_turn_never_exceeds_the_limits():
    rng = np.random.default_rng(1)
    headings = random_headings(rng, 1000)
    new_headings = turn(headings, rng.uniform(-10, 10, (1000, 3)), rng.uniform(-10, 10, (1000, 3)), MAX_YAW, MAX_PITCH, V / L)
    yaw_change = np.abs((new_headings[..., 0] - headings[..., 0] + np.pi) % (2 * np.pi) - np.pi)
    assert np.all(yaw_change <= MAX_YAW + 1e-9)
    assert np.all(np.abs(new_headings[..., 1] - headings[..., 1]) <= MAX_PITCH + 1e-9)
    assert np.all(np.abs(new_headings[..., 1]) <= np.pi / 2)
    # The axis length bounds the turn radius: at most v / L of heading change per step.
    turned = angle(heading_vectors(headings), heading_vectors(new_headings))
    assert np.all(turned <= V / L + 1e-9)
    assert np.any(turned[:, 1] > 0.9 * V[1] / L), "the targeter's turn-radius cap should bind somewhere"
    assert np.any(turned[:, 0] > V[1] / L), "the attacker turns further than the targeter can"


def test_zero_turn_is_a_straight_line():
    rng = np.random.default_rng(2)
    headings = random_headings(rng, 50)
    positions = rng.normal(size=(50, 3, 3))
    new_headings = turn(headings, np.zeros((50, 3)), np.zeros((50, 3)), MAX_YAW, MAX_PITCH, V / L)
    np.testing.assert_allclose(new_headings, headings, atol=1e-15)
    new_positions = move(positions, headings, new_headings, V)
    np.testing.assert_allclose(new_positions - positions, V[:, None] * heading_vectors(headings), atol=1e-12)


def test_yaw_wraps_into_zero_two_pi():
    headings = np.array([[[1.9 * np.pi, 0.0], [0.1, 0.0], [0.0, 0.0]]])
    commanded = turn(headings, np.array([[0.5 * np.pi, -0.5 * np.pi, 0.0]]), np.zeros((1, 3)), MAX_YAW, MAX_PITCH)
    np.testing.assert_allclose(commanded[0, :, 0], [0.4 * np.pi, 0.1 - 0.5 * np.pi + 2 * np.pi, 0.0])
    assert np.all((commanded[..., 0] >= 0) & (commanded[..., 0] < 2 * np.pi))


def test_pitch_is_clamped_to_vertical():
    headings = np.array([[[0.0, np.pi / 2 - 0.1], [0.0, -np.pi / 2 + 0.1], [0.0, 0.0]]])
    commanded = turn(headings, np.zeros((1, 3)), np.array([[1.0, -1.0, 0.0]]), MAX_YAW, MAX_PITCH)
    np.testing.assert_allclose(commanded[0, :, 1], [np.pi / 2, -np.pi / 2, 0.0])


def test_absolute_action_reaches_a_near_heading_and_clips_a_far_one():
    game = BatchedGame(GameConfig(action_mode="absolute"), 1)
    game.reset(positions=np.array([[[0, 0, 0], [3, 0, 0], [1, 1, 0]]], dtype=float))
    actions = np.array([[[0.3, 0.2], [3.0, 1.5], [2 * np.pi - 0.1, -0.1]]])
    commanded = game.commanded_headings(actions)
    np.testing.assert_allclose(commanded[0, 0], [0.3, 0.2])  # within the limits: reached
    # Clipped to the limits, then scaled to the targeter's turn-radius bound v_T / L.
    assert np.hypot(*commanded[0, 1]) == pytest.approx(0.13 / 0.1)
    assert commanded[0, 1, 0] / commanded[0, 1, 1] == pytest.approx(2.0)
    np.testing.assert_allclose(commanded[0, 2], [2 * np.pi - 0.1, -0.1])  # the short way round


@pytest.mark.parametrize("action_mode", ["relative", "absolute"])
def test_both_action_modes_reach_the_same_heading(action_mode):
    relative, absolute = GameConfig(action_mode="relative"), GameConfig(action_mode="absolute")
    start = np.array([[[0, 0, 0], [3, 0, 0], [1, 1, 0]]], dtype=float)
    games = {}
    for name, cfg in (("relative", relative), ("absolute", absolute)):
        games[name] = BatchedGame(cfg, 1)
        games[name].reset(positions=start)
    games["relative"].step(np.array([[[0.5, -0.5], [1.0, 1.0], [-0.2, 0.0]]]))
    target = games["relative"].headings.copy()
    games["absolute"].step(target)
    np.testing.assert_allclose(games["absolute"].positions, games["relative"].positions, atol=1e-12)
    np.testing.assert_allclose(games[action_mode].headings, target, atol=1e-12)
