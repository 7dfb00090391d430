"""The league's RLlib wiring, in process, on one Ray instance for the module."""

import math

import pytest
import ray

from league.config import RunConfig
from league.players import Player
from league.rllib_bridge import MatchPlan, build_config, match_counts, set_match_plan, set_trainable


def trained(result, module):
    """Module steps trained in this iteration (a stale key of an idle module reads NaN)."""
    value = result["learners"].get(module, {}).get("num_module_steps_trained", 0)
    return 0 if math.isnan(value) else value


@pytest.fixture(scope="module")
def algo():
    ray.init(num_cpus=2, include_dashboard=False)
    run = RunConfig(
        name="wiring",
        ppo={"train_batch_size": 200, "minibatch_size": 100, "num_epochs": 1, "hidden": [16]},
        resources={"num_envs_per_env_runner": 2},
    )
    scripted_attacker = Player(id=3, side="attacker", kind="scripted", version=0, scripted_attacker="lead_intercept")
    scripted_team = Player(
        id=4, side="team", kind="scripted", version=0, scripted_targeter="avoid_attacker", scripted_defender="pure_pursuit"
    )
    plan = MatchPlan({"targeter": "team", "defender": "team"}, [scripted_attacker.modules()], [1.0], seed=0)
    algorithm = build_config(run, [scripted_attacker, scripted_team], plan).build_algo()
    yield algorithm
    algorithm.stop()
    ray.shutdown()


def test_one_shared_team_policy_plays_and_learns_for_both_t_and_d(algo):
    set_trainable(algo, ["team"])
    result = algo.train()
    sampled = result["env_runners"]["num_module_steps_sampled"]
    agents = result["env_runners"]["num_agent_steps_sampled"]
    assert agents["targeter"] > 0 and agents["defender"] > 0
    assert sampled["team"] == agents["targeter"] + agents["defender"]
    assert trained(result, "team") > 0 and trained(result, "attacker") == 0
    modules = {m for m, _, _ in match_counts(result)}
    assert modules <= {("scripted-attacker-lead_intercept", "team", "team")} and modules


def test_switching_sides_trains_only_the_attacker(algo):
    plan = MatchPlan(
        {"attacker": "attacker"},
        [{"targeter": "scripted-targeter-avoid_attacker", "defender": "scripted-defender-pure_pursuit"}],
        [1.0],
        seed=1,
    )
    set_match_plan(algo, plan)
    set_trainable(algo, ["attacker"])
    algo.train()  # episodes begun under the old plan end here
    result = algo.train()
    assert trained(result, "attacker") > 0 and trained(result, "team") == 0
    played = {m for m, _, _ in match_counts(result)}
    assert ("attacker", "scripted-targeter-avoid_attacker", "scripted-defender-pure_pursuit") in played
