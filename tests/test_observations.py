"""Observation layouts as documented in envs.observations."""

import numpy as np
import pytest

from envs.agents import AGENTS
from envs.config import GameConfig
from envs.core import BatchedGame

START = np.array([[[1.0, 2.0, 3.0], [2.0, 0.0, 0.0], [0.0, 4.0, 0.0]]])


def observations(**overrides):
    game = BatchedGame(GameConfig(**overrides), 1)
    game.reset(positions=START)
    return game, dict(zip(AGENTS, (o[0] for o in game.observations())))


def test_paper_layout_and_role():
    _, obs = observations(observation="paper")
    expected = [1, 2, 3, 0, 4, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0]
    np.testing.assert_array_equal(obs["attacker"], expected)
    np.testing.assert_array_equal(obs["targeter"], expected + [1, 0])
    np.testing.assert_array_equal(obs["defender"], expected + [0, 1])


def test_rich_layout_is_agent_centred():
    game, obs = observations()
    scale = game.config.position_scale
    t = obs["targeter"]
    assert t.shape == (27,) and obs["attacker"].shape == (25,)
    np.testing.assert_allclose(t[0:3], START[0, 1] / scale)
    np.testing.assert_allclose(t[3:6], [1, 0, 0])  # heading yaw = pitch = 0
    np.testing.assert_allclose(t[6:9], (START[0, 0] - START[0, 1]) / scale, rtol=1e-6)  # A first
    assert t[9] == pytest.approx(np.linalg.norm(START[0, 0] - START[0, 1]) / scale)
    np.testing.assert_allclose(t[13:16], (START[0, 2] - START[0, 1]) / scale, rtol=1e-6)  # then D
    np.testing.assert_allclose(t[20:23], -START[0, 1] / scale)
    assert t[23] == pytest.approx(2.0 / scale)
    assert t[24] == 1.0  # all of the time limit left
    np.testing.assert_array_equal(t[25:], [1, 0])
    np.testing.assert_array_equal(obs["defender"][25:], [0, 1])


def test_time_left_counts_down_and_global_state_size():
    game, _ = observations()
    game.step(np.zeros((1, 3, 2)))
    assert game.observations()[0][0, 24] == pytest.approx(1 - 1 / game.time_limit[0])
    assert game.global_state().shape == (1, 22)
