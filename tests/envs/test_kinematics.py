"""The motion model: constant speed, turn limits, the axis-length bound, straight flight, U-turns, angle wrapping."""

import math

import numpy as np
import pytest

from envs.config import GameConfig
from envs.core import BatchedGame
from envs.kinematics import TURN_ANGLE_TOLERANCE, Arcs, heading_vectors, limit_turn, move, turned

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
    change = limit_turn(headings, rng.uniform(-2, 2, (500, 3)), rng.uniform(-1, 1, (500, 3)), MAX_YAW, MAX_PITCH, V / L)
    new_headings = turned(headings, change)
    positions = rng.normal(size=(500, 3, 3))
    new_positions = move(positions, headings, change, V)
    turned_by = angle(heading_vectors(headings), heading_vectors(new_headings))
    chord = np.linalg.norm(new_positions - positions, axis=-1)
    # An arc of length v turning by alpha has chord 2 (v / alpha) sin(alpha / 2).
    expected = np.where(turned_by > 1e-9, 2 * (V / np.maximum(turned_by, 1e-12)) * np.sin(turned_by / 2), V)
    np.testing.assert_allclose(chord, expected, rtol=1e-9, atol=1e-12)
    assert np.all(chord <= V + 1e-12)


def test_turn_never_exceeds_the_limits():
    rng = np.random.default_rng(1)
    headings = random_headings(rng, 1000)
    change = limit_turn(headings, rng.uniform(-10, 10, (1000, 3)), rng.uniform(-10, 10, (1000, 3)), MAX_YAW, MAX_PITCH, V / L)
    new_headings = turned(headings, change)
    yaw_change = np.abs((new_headings[..., 0] - headings[..., 0] + np.pi) % (2 * np.pi) - np.pi)
    assert np.all(yaw_change <= MAX_YAW + 1e-9)
    assert np.all(np.abs(new_headings[..., 1] - headings[..., 1]) <= MAX_PITCH + 1e-9)
    assert np.all(np.abs(new_headings[..., 1]) <= np.pi / 2)
    # The axis length bounds the turn radius: at most v / L of heading change per step.
    # 1e-9: arccos of a dot product of unit vectors is good to ~sqrt(1e-16) = 1e-8 near 0 and
    # ~1e-12 near 1.3 rad, where the bound binds.
    turned_by = angle(heading_vectors(headings), heading_vectors(new_headings))
    assert np.all(turned_by <= V / L + 1e-9)
    assert np.any(turned_by[:, 1] > 0.9 * V[1] / L), "the targeter's turn-radius cap should bind somewhere"
    assert np.any(turned_by[:, 0] > V[1] / L), "the attacker turns further than the targeter can"


def test_zero_turn_is_a_straight_line():
    rng = np.random.default_rng(2)
    headings = random_headings(rng, 50)
    positions = rng.normal(size=(50, 3, 3))
    change = limit_turn(headings, np.zeros((50, 3)), np.zeros((50, 3)), MAX_YAW, MAX_PITCH, V / L)
    np.testing.assert_allclose(turned(headings, change), headings, atol=1e-15)
    new_positions = move(positions, headings, change, V)
    np.testing.assert_allclose(new_positions - positions, V[:, None] * heading_vectors(headings), atol=1e-12)


def test_yaw_wraps_into_zero_two_pi():
    headings = np.array([[[1.9 * np.pi, 0.0], [0.1, 0.0], [0.0, 0.0]]])
    yaw_command = np.array([[0.5 * np.pi, -0.5 * np.pi, 0.0]])
    commanded = turned(headings, limit_turn(headings, yaw_command, np.zeros((1, 3)), MAX_YAW, MAX_PITCH))
    np.testing.assert_allclose(commanded[0, :, 0], [0.4 * np.pi, 0.1 - 0.5 * np.pi + 2 * np.pi, 0.0])
    assert np.all((commanded[..., 0] >= 0) & (commanded[..., 0] < 2 * np.pi))


def test_pitch_is_clamped_to_vertical():
    headings = np.array([[[0.0, np.pi / 2 - 0.1], [0.0, -np.pi / 2 + 0.1], [0.0, 0.0]]])
    pitch_command = np.array([[1.0, -1.0, 0.0]])
    commanded = turned(headings, limit_turn(headings, np.zeros((1, 3)), pitch_command, MAX_YAW, MAX_PITCH))
    np.testing.assert_allclose(commanded[0, :, 1], [np.pi / 2, -np.pi / 2, 0.0])


def test_absolute_action_reaches_a_near_heading_and_clips_a_far_one():
    game = BatchedGame(GameConfig(action_mode="absolute"), 1)
    game.reset(positions=np.array([[[0, 0, 0], [3, 0, 0], [1, 1, 0]]], dtype=float))
    actions = np.array([[[0.3, 0.2], [3.0, 1.5], [2 * np.pi - 0.1, -0.1]]])
    commanded = turned(game.headings, game.commanded_turn(actions))
    np.testing.assert_allclose(commanded[0, 0], [0.3, 0.2])  # within the limits: reached
    # Clipped to (pi/2, pi/4), then scaled until T's true turn is its bound v_T / L = 1.3 rad.
    targeter = heading_vectors(commanded[0, 1])
    assert np.arccos(targeter @ heading_vectors(np.zeros(2))) == pytest.approx(0.13 / 0.1, abs=1e-12)
    assert commanded[0, 1, 0] / commanded[0, 1, 1] == pytest.approx(2.0)  # the command's direction is kept
    np.testing.assert_allclose(commanded[0, 2], [2 * np.pi - 0.1, -0.1])  # the short way round


def targeter_turn(pitch, yaw_command, pitch_command, axis_length=0.1):
    """The (yaw, pitch) change of T's relative command from heading (0, pitch)."""
    game = BatchedGame(GameConfig(axis_length=axis_length), 1)
    game.reset(positions=np.array([[[0, 0, 0], [3, 0, 0], [1, 1, 0]]], dtype=float))
    game.headings[0, 1] = [0.0, pitch]
    return game.commanded_turn(np.array([[[0, 0], [yaw_command, pitch_command], [0, 0]]], dtype=float))[0, 1]


def test_axis_length_bounds_the_true_angle_not_the_command_length():
    # A pure yaw turn at pitch 0 turns the heading by exactly its yaw change: pi/2 > 1.3 is cut to 1.3.
    np.testing.assert_allclose(targeter_turn(0.0, 1, 0), [1.3, 0.0], atol=1e-12)
    # From pitch 1.0, yaw pi/2 and pitch pi/8 turn the heading by
    # 2 asin(sqrt(sin^2(pi/16) + cos(1) cos(1 + pi/8) sin^2(pi/4))) = 0.595 rad < 1.3: not cut,
    # though the command's length sqrt((pi/2)^2 + (pi/8)^2) = 1.62 exceeds 1.3.
    np.testing.assert_allclose(targeter_turn(1.0, 1, 0.5), [np.pi / 2, np.pi / 8], atol=1e-15)


def test_axis_length_applies_after_the_pitch_clamp():
    # From pitch 1.5 a full (yaw, pitch) command is clamped to pitch pi/2 - 1.5 = 0.0708 and
    # turns the heading by only 0.0708 rad (to the pole): nothing to cut, all of pi/2 of yaw is kept.
    np.testing.assert_allclose(targeter_turn(1.5, 1, 1), [np.pi / 2, np.pi / 2 - 1.5], atol=1e-15)


def test_axis_length_zero_leaves_the_paper_limits_alone():
    np.testing.assert_allclose(targeter_turn(0.0, 1, 1, axis_length=0.0), [np.pi / 2, np.pi / 4], atol=1e-15)
    assert GameConfig(axis_length=0.0).axis_length == 0.0


@pytest.mark.parametrize("yaw_command, side", [(1.0, 1.0), (-1.0, -1.0)])
def test_exact_u_turn_turns_in_the_commanded_plane(yaw_command, side):
    # max_yaw_change = pi and no axis length: a full yaw command reverses the heading in one step.
    config = GameConfig(max_yaw_change=np.pi, axis_length=0.0)
    game = BatchedGame(config, 1)
    game.reset(positions=np.array([[[0, 0, 0], [3, 0, 0], [1, 1, 0]]], dtype=float))
    game.step(np.array([[[yaw_command, 0.0], [0, 0], [0, 0]]]))
    np.testing.assert_allclose(heading_vectors(game.headings[0, 0]), [-1.0, 0.0, 0.0], atol=1e-15)
    # A half circle of length v: radius v / pi, ending 2 v / pi to the side it turned to.
    np.testing.assert_allclose(game.positions[0, 0], [0.0, side * 2 * 0.18 / np.pi, 0.0], atol=1e-15)


def test_arc_points_lie_on_one_circle_at_constant_speed():
    rng = np.random.default_rng(3)
    headings = random_headings(rng, 200)
    change = limit_turn(headings, rng.uniform(-2, 2, (200, 3)), rng.uniform(-1, 1, (200, 3)), MAX_YAW, MAX_PITCH, V / L)
    positions = rng.normal(size=(200, 3, 3))
    arcs = Arcs.of_turn(positions, headings, turned(headings, change), change, V)
    fractions = np.linspace(0, 1, 2001)[:, None, None]
    points = arcs.at(fractions)
    np.testing.assert_allclose(points[0], positions, atol=1e-15)
    np.testing.assert_allclose(points[-1], arcs.end, atol=1e-15)
    # Summed over 2000 pieces, chords give the path length v to (v a / 2000)^2 / 24 relative ~ 1e-8.
    length = np.linalg.norm(np.diff(points, axis=0), axis=-1).sum(axis=0)
    np.testing.assert_allclose(length, np.broadcast_to(V, length.shape), rtol=1e-7)
    turning = arcs.angle > 1e-3
    radius = V / np.where(turning, arcs.angle, 1.0)
    centre = positions + radius[..., None] * arcs.normal
    from_centre = np.linalg.norm(points - centre, axis=-1)
    expected = np.broadcast_to(radius, from_centre.shape)
    np.testing.assert_allclose(from_centre[:, turning], expected[:, turning], rtol=1e-9)


def test_relative_actions_turn_by_fractions_of_the_limits_and_absolute_actions_reach_the_same_heading():
    relative, absolute = GameConfig(action_mode="relative"), GameConfig(action_mode="absolute")
    start = np.array([[[0, 0, 0], [3, 0, 0], [1, 1, 0]]], dtype=float)  # every heading yaw = pitch = 0
    games = {}
    for name, cfg in (("relative", relative), ("absolute", absolute)):
        games[name] = BatchedGame(cfg, 1)
        games[name].reset(positions=start)
    games["relative"].step(np.array([[[0.5, -0.5], [1.0, 1.0], [-0.2, 0.0]]]))
    reached = games["relative"].headings[0]
    # A and D: the commanded fractions of the limits (yaw pi/2, pitch pi/4), within v / L; a few
    # float operations from the action, so 1e-12.
    np.testing.assert_allclose(reached[0], [math.pi / 4, -math.pi / 8], atol=1e-12)
    np.testing.assert_allclose(reached[2], [2 * math.pi - 0.1 * math.pi, 0.0], atol=1e-12)
    # T asked for (pi/2, pi/4), a turn of pi/2 > v_T / L = 1.3 rad: cut to 1.3 rad, yaw : pitch kept 2 : 1.
    # abs: the cut is solved to TURN_ANGLE_TOLERANCE of the angle (envs.kinematics).
    assert angle(heading_vectors(np.zeros(2)), heading_vectors(reached[1])) == pytest.approx(V[1] / L, abs=TURN_ANGLE_TOLERANCE)
    assert reached[1, 0] == pytest.approx(2 * reached[1, 1], abs=1e-12)
    games["absolute"].step(reached[None])
    np.testing.assert_allclose(games["absolute"].headings, games["relative"].headings, atol=1e-12)
    np.testing.assert_allclose(games["absolute"].positions, games["relative"].positions, atol=1e-12)
