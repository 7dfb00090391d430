"""The league's RLlib wiring, in process, on one Ray instance for the module."""

import math

import pytest

from league.config import RunConfig
from league.core.players import Player
from league.core.match_plan import MatchPlan
from league.rllib.bridge import (
    build_config, episode_outcomes, learner_env_steps, learner_spec, set_match_plan, set_trainable,
)


def trained(result, module):
    """Module steps trained in this iteration (a stale key of an idle module reads NaN)."""
    value = result["learners"].get(module, {}).get("num_module_steps_trained", 0)
    return 0 if math.isnan(value) else value


@pytest.fixture(scope="module")
def algo(ray_instance):
    run = RunConfig(
        name="wiring",
        ppo={"train_batch_size": 200, "minibatch_size": 100, "num_epochs": 1, "hidden": [16]},
        resources={"num_envs_per_env_runner": 2},
    )
    scripted_attacker = Player(id=3, side="attacker", kind="scripted", version=0, scripted_attacker="lead_intercept")
    scripted_team = Player(
        id=4, side="team", kind="scripted", version=0, scripted_targeter="avoid_attacker", scripted_defender="pure_pursuit"
    )
    learners = [
        Player(id=1, side="attacker", kind="learner", version=0, reward_method=2),
        Player(id=2, side="team", kind="learner", version=0),
    ]
    plan = MatchPlan([{"targeter": "team", "defender": "team"}], [[scripted_attacker.modules()]], [[1.0]], seed=0)
    algorithm = build_config(run, [*learners, scripted_attacker, scripted_team], plan).build_algo()
    yield algorithm
    algorithm.stop()


def test_one_shared_team_policy_plays_and_learns_for_both_t_and_d(algo):
    set_trainable(algo, ["team"])
    result = algo.train()
    sampled = result["env_runners"]["num_module_steps_sampled"]
    agents = result["env_runners"]["num_agent_steps_sampled"]
    assert agents["targeter"] > 0 and agents["defender"] > 0
    assert sampled["team"] == agents["targeter"] + agents["defender"]
    # the team played every game, the attacker learner none: their env steps, exactly
    team, attacker = Player(id=2, side="team", kind="learner", version=0), Player("attacker", "learner", 0, 2, id=1)
    env_steps = result["env_runners"]["num_env_steps_sampled"]
    assert learner_env_steps(result, [team, attacker]) == {"team": env_steps, "attacker-m2": 0}
    assert trained(result, "team") > 0 and trained(result, "attacker-m2") == 0
    modules = {m for m, _, _ in episode_outcomes(result)}
    assert modules <= {("scripted-attacker-lead_intercept", "team", "team")} and modules


def test_switching_sides_trains_only_the_attacker(algo):
    plan = MatchPlan(
        [{"attacker": "attacker-m2"}],
        [[{"targeter": "scripted-targeter-avoid_attacker", "defender": "scripted-defender-pure_pursuit"}]],
        [[1.0]],
        seed=1,
    )
    set_match_plan(algo, plan)
    set_trainable(algo, ["attacker-m2"])
    algo.train()  # episodes begun under the old plan end here
    result = algo.train()
    assert trained(result, "attacker-m2") > 0 and trained(result, "team") == 0
    played = {m for m, _, _ in episode_outcomes(result)}
    assert ("attacker-m2", "scripted-targeter-avoid_attacker", "scripted-defender-pure_pursuit") in played


def test_reward_connector_pays_each_attacker_module_its_own_method(algo):
    import numpy as np

    from league.rllib.callbacks import AttackerRewardByMethod
    from ray.rllib.connectors.learner.add_one_ts_to_episodes_and_truncate import AddOneTsToEpisodesAndTruncate

    episodes = algo.env_runner.sample(num_episodes=3, random_actions=True, force_reset=True)
    assert {ep.module_for("attacker") for ep in episodes} == {"attacker-m2"}
    paid_by_env = [ep.agent_episodes["attacker"].get_rewards().copy() for ep in episodes]
    method_three = {"attacker-m2": learner_spec(RunConfig(name="wiring"), "attacker", 3).build()}  # env pays method 2
    AddOneTsToEpisodesAndTruncate()(rl_module=method_three, batch={}, episodes=episodes, shared_data={})
    AttackerRewardByMethod()(rl_module=method_three, batch={}, episodes=episodes)
    changed = False
    for episode, before in zip(episodes, paid_by_env):
        attacker = episode.agent_episodes["attacker"]
        real = len(attacker) - 1
        infos = attacker.get_infos(slice(1, real + 1))
        expected = [info["attacker_rewards"][2] for info in infos]
        np.testing.assert_allclose(attacker.get_rewards()[:real], expected, rtol=1e-6)
        np.testing.assert_allclose(before, [info["attacker_rewards"][1] for info in infos], rtol=1e-6)
        changed |= not np.allclose(before, expected)
    assert changed


def test_snapshots_carry_the_learners_weights_into_sampling_files_and_checkpoints(algo, tmp_path):
    import numpy as np
    from ray.rllib.algorithms.algorithm import Algorithm

    from league.evaluation.engine import load_module
    from league.rllib.bridge import add_snapshot, learner_weights, save_module

    run = RunConfig(name="wiring", ppo={"hidden": [16]})
    snapshot = Player(id=9, side="attacker", kind="snapshot", version=7, reward_method=2)
    source = learner_weights(algo, "attacker-m2")
    add_snapshot(algo, run, snapshot, "attacker-m2")
    sampling = algo.get_module(snapshot.name).state_dict()
    for key, value in source.items():
        np.testing.assert_array_equal(sampling[key].numpy(), value)
    save_module(algo, snapshot.name, tmp_path / "module")
    saved = load_module(tmp_path / "module").state_dict()
    for key, value in source.items():
        np.testing.assert_array_equal(saved[key].numpy(), value)
    algo.save_to_path(str(tmp_path / "checkpoint"))
    restored = Algorithm.from_checkpoint(str(tmp_path / "checkpoint"))
    try:
        after = restored.get_module(snapshot.name).state_dict()  # a module added at run time comes back
        for key, value in source.items():
            np.testing.assert_array_equal(after[key].numpy(), value)
    finally:
        restored.stop()
