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


def test_rich_layout_is_egocentric():
    game, obs = observations()
    scale = game.config.position_scale
    t = obs["targeter"]
    assert t.shape == (23,) and obs["attacker"].shape == (21,)
    np.testing.assert_allclose(t[0:2], [0, 1])  # pitch 0
    # Yaw 0: the yaw frame is the world frame.
    np.testing.assert_allclose(t[2:5], (START[0, 0] - START[0, 1]) / scale, rtol=1e-6)  # A first
    assert t[5] == pytest.approx(np.linalg.norm(START[0, 0] - START[0, 1]) / scale)
    np.testing.assert_allclose(t[6:9], [1, 0, 0])  # A's heading
    np.testing.assert_allclose(t[9:12], (START[0, 2] - START[0, 1]) / scale, rtol=1e-6)  # then D
    np.testing.assert_allclose(t[16:19], -START[0, 1] / scale)
    assert t[19] == pytest.approx(2.0 / scale)
    assert t[20] == 1.0  # all of the time limit left
    np.testing.assert_array_equal(t[21:], [1, 0])
    np.testing.assert_array_equal(obs["defender"][21:], [0, 1])


def test_rich_view_turns_with_the_agent():
    # Facing +y (yaw pi/2), a target at +y world lies straight ahead (+x of the yaw frame).
    game = BatchedGame(GameConfig(), 1)
    game.reset(positions=np.array([[[0.0, 0.0, 0.0], [0.0, 2.0, 0.0], [4.0, 0.0, 0.0]]]))
    game.headings[0, 0] = [np.pi / 2, 0.3]
    attacker = game.observations()[0][0]
    np.testing.assert_allclose(attacker[0:2], [np.sin(0.3), np.cos(0.3)], rtol=1e-6)
    np.testing.assert_allclose(attacker[2:5], [0.5, 0.0, 0.0], atol=1e-7)  # T ahead
    np.testing.assert_allclose(attacker[9:12], [0.0, -1.0, 0.0], atol=1e-7)  # D on the right


def test_time_left_counts_down_and_global_state_size():
    game, _ = observations()
    game.step(np.zeros((1, 3, 2)))
    assert game.observations()[0][0, 20] == pytest.approx(1 - 1 / game.time_limit[0])
    assert game.global_state().shape == (1, 22)


@pytest.mark.parametrize("observation,memory", [("paper", False), ("rich", False), ("rich", True)])
def test_policy_input_is_own_observation_then_global_state(observation, memory):
    from envs.observations import policy_input, policy_input_size, split_policy_input
    from envs.vector_env import TargetDefenseVectorEnv

    config = GameConfig(observation=observation, attacker_memory=memory)
    env = TargetDefenseVectorEnv({**config.model_dump(), "with_global_state": True}, 3)
    inputs = env.reset(seed=5)
    core = env.core
    for index, agent in enumerate(AGENTS):
        assert inputs[agent].shape == (3, policy_input_size(config, index))  # the size needs no env
        own, state = split_policy_input(inputs[agent], inputs[agent].shape[1] - 22)
        np.testing.assert_array_equal(own, core.observations()[index])
        np.testing.assert_array_equal(state, core.global_state())
        np.testing.assert_array_equal(policy_input(own, state), inputs[agent])
    # the paper's 15 numbers, the rich 21; T and D add their role one-hot
    assert [policy_input_size(config, i) - 22 for i in range(3)] == (
        [15, 17, 17] if observation == "paper" else [21 + memory, 23, 23]
    )


def test_the_attackers_memory_tells_a_straight_flying_targeter_from_one_that_hides():
    from envs.match import scripted_players
    from envs.scenarios import evaluation_scenarios

    starts = evaluation_scenarios("default", 200)
    memories = {}
    for targeter in ("straight", "avoid_oncoming_attacker"):
        players = scripted_players("lead_intercept", targeter, "pure_pursuit")
        game = BatchedGame(GameConfig(attacker_memory=True), len(starts))
        game.reset(positions=starts)
        seen = [game.observations()[0][:, -1]]
        while game.active.any():
            game.step(np.stack([players[agent].act(game) for agent in AGENTS], axis=1))
            attacker, targeter_obs, _ = game.observations()
            assert attacker.shape == (200, 22) and targeter_obs.shape == (200, 23)  # only A remembers
            seen.append(attacker[:, -1])
        memories[targeter] = np.stack(seen)
        game.reset_games(np.arange(10), positions=starts[:10])
        assert not game.observations()[0][:10, -1].any()  # a new game starts with nothing to remember
    assert memories["straight"].max() < 1e-6  # flying at the terminal never turns T away from it
    hides = memories["avoid_oncoming_attacker"]
    assert np.all(np.diff(hides, axis=0) >= 0)  # remembered after T turns back home
    assert np.mean(hides[-1] > 0.05) > 0.5  # lead intercept comes at T: most such T turn to hide

