"""The batched sampler against RLlib's standard one: same episodes, same training data."""

import numpy as np
import pytest
import torch
from torch import nn

from envs.agents import AGENTS
from league.rllib import compat
from league.rllib.env_runner import BatchedEnvRunner, SeededEnvRunner
from league.config import RunConfig
from league.core.players import Player
from league.core.match_plan import MatchPlan
from league.core.seeding import Purpose, stream_seed
from league.rllib.bridge import build_config, episode_outcomes, set_trainable
from ray.rllib.core.columns import Columns

GAMES = 4
ATTACKER = Player(id=1, side="attacker", kind="learner", version=0, reward_method=2)
TEAM = Player(id=2, side="team", kind="learner", version=0)
SCRIPTED_TEAM = Player(
    id=3, side="team", kind="scripted", version=0, scripted_targeter="avoid_attacker", scripted_defender="pure_pursuit"
)


class RowByRow(nn.Module):
    """``inner`` applied to one row at a time.

    A matrix product over several rows sums in another order than over one row (torch picks
    its kernel by batch size), so the same policy gives actions 1 to 8 float32 ulps apart in
    the standard sampler (one game per forward pass) and the batched one (all games at once);
    the game's dynamics then amplify that to ~1e-4 within an episode. Computed row by row,
    both samplers' actions are the same bits, and so must be everything that follows.
    """

    def __init__(self, inner: nn.Module):
        super().__init__()
        self.inner = inner

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        rows = x.reshape(-1, x.shape[-1])
        return torch.cat([self.inner(row) for row in rows.split(1)]).reshape(*x.shape[:-1], -1)


def build(sampler, team):
    run = RunConfig(
        name="sampler",
        seed=5,
        ppo={"train_batch_size": 240, "minibatch_size": 120, "num_epochs": 1, "hidden": [16]},
        resources={"num_envs_per_env_runner": GAMES, "sampler": sampler},
    )
    plan = MatchPlan([{"attacker": ATTACKER.name}], [[team.modules()]], [[1.0]], seed=0)
    return build_config(run, [ATTACKER, TEAM, SCRIPTED_TEAM], plan).build_algo()


@pytest.fixture(scope="module")
def algos(ray_instance):
    built = {}
    for team in (TEAM, SCRIPTED_TEAM):
        standard, batched = build("standard", team), build("batched", team)
        # Same weights in both, scrambled so that the deterministic policies do not all fly
        # straight ahead into timeouts.
        torch.manual_seed(0)
        for name in (ATTACKER.name, TEAM.name):
            for parameter in standard.env_runner.module[name].parameters():
                parameter.data.normal_(0.0, 0.7)
        batched.env_runner.module.set_state(standard.env_runner.module.get_state())
        for algo in (standard, batched):
            for name in (ATTACKER.name, TEAM.name):
                module = algo.env_runner.module[name]
                module.pi = RowByRow(module.pi)
        built[team.name] = (standard, batched)
    yield built
    for pair in built.values():
        for algo in pair:
            algo.stop()


def finished_episodes(algo, calls, explore=False):
    """Data of the episodes that ended within ``calls`` samples, chunks joined, by first observation."""
    chunks = {}
    for _ in range(calls):
        for chunk in algo.env_runner.sample(num_timesteps=GAMES * 7, explore=explore):
            chunks.setdefault(chunk.id_, []).append(chunk)
    episodes = {}
    for parts in chunks.values():
        if not parts[-1].is_done:
            continue
        agents = sorted(parts[0].agent_episodes)
        data = {}
        for agent in agents:
            pieces = [p.agent_episodes[agent] for p in parts]
            data[agent] = {
                "observations": np.concatenate([pieces[0].get_observations()[:1]] + [p.get_observations()[1:] for p in pieces]),
                "actions": np.concatenate([p.get_actions() for p in pieces]),
                "rewards": np.concatenate([p.get_rewards() for p in pieces]),
                "infos": [info for p in pieces for info in p.get_infos()[1:]],
                "modules": parts[0].module_for(agent),
            }
        first = data[agents[0]]["observations"][0]
        episodes[first.round(5).tobytes()] = data
    return episodes


def assert_same(standard, batched, agents):
    common = standard.keys() & batched.keys()
    # Both ran the same seeded starts; all but the episodes cut at the end overlap.
    assert len(common) >= 0.8 * min(len(standard), len(batched)) and len(common) >= 10
    for key in common:
        for agent in agents:
            a, b = standard[key][agent], batched[key][agent]
            np.testing.assert_array_equal(b["observations"], a["observations"])
            np.testing.assert_array_equal(b["actions"], a["actions"])
            np.testing.assert_array_equal(b["rewards"], a["rewards"])
            assert b["infos"] == a["infos"]  # steps, time limit, outcome, A's reward by method
            assert b["modules"] == a["modules"]
        assert standard[key][agents[0]]["infos"][-1]["outcome"] == batched[key][agents[0]]["infos"][-1]["outcome"]


def test_the_sampler_is_chosen_by_config(algos):
    standard, batched = algos[TEAM.name]
    assert type(standard.env_runner) is SeededEnvRunner
    assert isinstance(batched.env_runner, BatchedEnvRunner)


def test_both_samplers_start_their_games_from_the_runs_own_stream(algos):
    for algo in algos[TEAM.name]:
        assert compat.env_runner_seed(algo.env_runner) == stream_seed(5, Purpose.GAME_STARTS, 0)


def test_same_seeds_and_deterministic_policies_give_the_same_episodes(algos):
    standard, batched = algos[TEAM.name]  # both sides learned: every agent is in the episodes
    a, b = finished_episodes(standard, 40), finished_episodes(batched, 40)
    assert_same(a, b, AGENTS)


def test_against_scripted_players_only_the_learner_is_handed_over(algos):
    standard, batched = algos[SCRIPTED_TEAM.name]
    set_trainable(standard, [ATTACKER.name])
    set_trainable(batched, [ATTACKER.name])
    a, b = finished_episodes(standard, 40), finished_episodes(batched, 40)
    assert all(set(data) == {"attacker"} for data in b.values())
    assert all(set(data) == set(AGENTS) for data in a.values())
    assert_same(a, b, ["attacker"])
    outcomes = {data["attacker"]["infos"][-1]["outcome"] for data in b.values()}
    assert len(outcomes) >= 2, outcomes
    chunk = batched.env_runner.sample(num_timesteps=GAMES * 3)[0]
    assert [chunk.module_for(agent) for agent in AGENTS] == ["attacker-m2", *SCRIPTED_TEAM.modules().values()]


def test_exploring_stores_the_distribution_and_the_sampled_actions_likelihood(algos):
    standard, batched = algos[TEAM.name]
    batched_chunks = batched.env_runner.sample(num_timesteps=GAMES * 5, explore=True)
    standard_chunks = standard.env_runner.sample(num_timesteps=GAMES * 5, explore=True)
    module = batched.env_runner.module[TEAM.name]
    for chunk in batched_chunks:
        episode = chunk.agent_episodes["defender"]
        outputs = episode.extra_model_outputs
        assert set(outputs) == set(standard_chunks[0].agent_episodes["defender"].extra_model_outputs)
        dist = module.get_exploration_action_dist_cls().from_logits(torch.from_numpy(outputs[Columns.ACTION_DIST_INPUTS].data))
        logp = dist.logp(torch.from_numpy(episode.actions.data)).numpy()
        np.testing.assert_allclose(outputs[Columns.ACTION_LOGP].data, logp, rtol=1e-5, atol=1e-5)


def test_training_on_batched_samples_counts_steps_matches_and_returns(algos):
    _, batched = algos[SCRIPTED_TEAM.name]
    set_trainable(batched, [ATTACKER.name])
    result = batched.train()
    runners = result["env_runners"]
    assert runners["num_env_steps_sampled"] >= 240
    assert runners["num_agent_steps_sampled"]["attacker"] == runners["num_env_steps_sampled"]
    assert runners["num_module_steps_sampled"]["attacker-m2"] == runners["num_env_steps_sampled"]
    assert result["learners"]["attacker-m2"]["num_module_steps_trained"] > 0
    assert "attacker-m2" in runners["module_episode_returns_mean"]
    played = episode_outcomes(result)
    assert played and all(modules == ("attacker-m2", *SCRIPTED_TEAM.modules().values()) for modules, _, _ in played)
    assert sum(count for _, _, count in played) == runners["num_episodes"]
