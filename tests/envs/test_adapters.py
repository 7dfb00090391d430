"""PettingZoo API checks, and the batched core, PettingZoo env, RLlib env and vector env in lockstep."""

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

from envs.agents import AGENTS
from envs.config import GameConfig
from envs.core import BatchedGame
from envs.pettingzoo_env import TargetDefenseEnv, parallel_env
from envs.rllib_env import TargetDefenseMultiAgentEnv
from envs.scenarios import evaluation_scenarios
from envs.vector_env import TargetDefenseVectorEnv

MODES = [("rich", "relative"), ("paper", "absolute"), ("paper", "relative"), ("rich", "absolute")]


@pytest.mark.parametrize("observation, action_mode", MODES)
def test_pettingzoo_parallel_api(observation, action_mode):
    parallel_api_test(parallel_env(observation=observation, action_mode=action_mode), num_cycles=300)


@pytest.mark.parametrize("attacker_reward", [1, 2, 3])
def test_pettingzoo_seeding(attacker_reward):
    parallel_seed_test(lambda: parallel_env(attacker_reward=attacker_reward), num_cycles=300)


def test_same_seed_same_game_in_all_three():
    seed = 123
    core = BatchedGame(GameConfig(), 1)
    core.reset(np.random.default_rng(seed))
    pz_obs, _ = TargetDefenseEnv().reset(seed=seed)
    rl_obs, _ = TargetDefenseMultiAgentEnv().reset(seed=seed)
    for agent, obs in zip(AGENTS, core.observations()):
        np.testing.assert_array_equal(pz_obs[agent], obs[0])
        np.testing.assert_array_equal(rl_obs[agent], obs[0])


@pytest.mark.parametrize("attacker_reward, action_mode", [(1, "relative"), (2, "absolute"), (3, "relative")])
def test_lockstep_batched_pettingzoo_rllib(attacker_reward, action_mode):
    config = GameConfig(attacker_reward=attacker_reward, action_mode=action_mode, terminal_reward=1.0)
    n = 6
    starts = evaluation_scenarios("default", n)
    core = BatchedGame(config, n)
    core.reset(positions=starts)
    pz = [TargetDefenseEnv(config) for _ in range(n)]
    rl = [TargetDefenseMultiAgentEnv(config.model_dump()) for _ in range(n)]
    for i in range(n):
        pz[i].reset(options={"positions": starts[i]})
        rl[i].reset(options={"positions": starts[i]})
    rng = np.random.default_rng(7)
    space = pz[0].action_space("attacker")
    done = np.zeros(n, dtype=bool)
    steps = 0
    while not done.all():
        actions = rng.uniform(space.low, space.high, size=(n, 3, 2))
        result = core.step(actions)
        core_obs = core.observations()
        for i in np.flatnonzero(~done):
            action = {agent: actions[i, k] for k, agent in enumerate(AGENTS)}
            pz_obs, pz_rew, pz_term, pz_trunc, pz_info = pz[i].step(action)
            rl_obs, rl_rew, rl_term, _, rl_info = rl[i].step(action)
            for k, agent in enumerate(AGENTS):
                np.testing.assert_array_equal(pz_obs[agent], core_obs[k][i])
                np.testing.assert_array_equal(rl_obs[agent], core_obs[k][i])
                assert pz_rew[agent] == rl_rew[agent] == result.rewards[i, k]
                assert pz_term[agent] == rl_term[agent] == bool(result.done[i])
                assert not pz_trunc[agent]
            if result.done[i]:
                assert pz_info["attacker"]["outcome"] == rl_info["attacker"]["outcome"]
                assert pz[i].agents == [] and rl_term["__all__"]
        done |= result.done
        steps += 1
    assert steps > 1


def test_vector_env_is_a_vector_of_rllib_envs_game_for_game():
    """Game i of the vector env seeded s plays as an RLlib env seeded s + i, resets included."""
    env_config = {"attacker_reward": 3, "terminal_reward": 5.0, "with_global_state": True}
    n, seed = 5, 11
    vector = TargetDefenseVectorEnv(env_config, n)
    observations = vector.reset(seed=seed)
    singles = [TargetDefenseMultiAgentEnv(env_config) for _ in range(n)]
    single_obs = [env.reset(seed=seed + i)[0] for i, env in enumerate(singles)]
    rng = np.random.default_rng(0)
    episodes = 0
    for _ in range(300):
        for i in range(n):
            for agent in AGENTS:
                np.testing.assert_array_equal(observations[agent][i], single_obs[i][agent])
        actions = {agent: rng.uniform(-1, 1, size=(n, 2)) for agent in AGENTS}
        step = vector.step(actions)
        for i, env in enumerate(singles):
            obs, rewards, terminateds, _, infos = env.step({agent: actions[agent][i] for agent in AGENTS})
            assert step.infos(i) == infos
            assert bool(step.done[i]) == terminateds["__all__"]
            for agent in AGENTS:
                assert step.rewards[agent][i] == rewards[agent]
                np.testing.assert_array_equal(step.observations[agent][i], obs[agent])
            single_obs[i] = env.reset()[0] if terminateds["__all__"] else obs
        episodes += int(step.done.sum())
        restarted = vector.reset_games(np.flatnonzero(step.done))
        observations = {agent: step.observations[agent].copy() for agent in AGENTS}
        for agent in AGENTS:
            observations[agent][step.done] = restarted[agent]
    assert episodes > 2 * n


def test_rllib_env_can_append_the_global_state():
    env = TargetDefenseMultiAgentEnv({"with_global_state": True})
    obs, _ = env.reset(seed=0)
    plain = TargetDefenseEnv()
    plain_obs, _ = plain.reset(seed=0)
    for agent in AGENTS:
        np.testing.assert_array_equal(obs[agent], np.concatenate((plain_obs[agent], plain.state())))
        assert env.observation_spaces[agent].contains(obs[agent])


@pytest.mark.parametrize(
    "action, message",
    [
        (np.array([np.nan, 0.0]), "NaN"),
        (np.zeros(3), "shape"),
        (np.zeros((2, 1)), "shape"),
    ],
)
def test_invalid_actions_are_rejected(action, message):
    env = TargetDefenseEnv()
    env.reset(seed=0)
    actions = {agent: np.zeros(2) for agent in AGENTS}
    actions["defender"] = action
    with pytest.raises(ValueError, match=message):
        env.step(actions)


def test_missing_agent_action_is_rejected():
    env = TargetDefenseEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="missing \\['defender'\\]"):
        env.step({"attacker": np.zeros(2), "targeter": np.zeros(2)})


def test_step_after_the_end_needs_a_reset():
    env = TargetDefenseEnv()
    env.reset(options={"positions": np.array([[-3.0, 3, 0], [-0.2, 0, 0], [-3, -3, 0]])})
    _, _, terminations, _, infos = env.step({agent: np.zeros(2) for agent in AGENTS})
    assert all(terminations.values()) and infos["targeter"]["outcome"] == "terminal_reached"
    with pytest.raises(RuntimeError, match="reset"):
        env.step({agent: np.zeros(2) for agent in AGENTS})


def test_rgb_array_render_draws_the_game_so_far():
    from envs.match import scripted_players

    env = parallel_env(render_mode="rgb_array")
    players = scripted_players("lead_intercept", "avoid_attacker", "pure_pursuit")
    env.reset(seed=0)
    first = env.render()
    for _ in range(15):
        if not env.agents:
            break
        core = env.game.core
        env.step({agent: players[agent].act(core)[0] for agent in env.agents})
    later = env.render()
    assert first.dtype == np.uint8 and first.ndim == 3 and first.shape[2] == 3 and first.shape == later.shape
    assert len(np.unique(later.reshape(-1, 3), axis=0)) > 20  # a picture, not a blank canvas
    assert not np.array_equal(first, later)  # the paths grew
    assert parallel_env().render() is None
    with pytest.raises(ValueError, match="render_mode"):
        parallel_env(render_mode="human")
