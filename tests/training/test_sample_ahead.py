"""Sampling overlapped with learning (``resources.sample_ahead``): the batch a Learner update
takes was sampled by the policy exactly one update old, a phase's end drops the batch sampled
ahead, and a run stays one run: two runs of one seed, and one killed and resumed, end alike."""

import numpy as np
import pytest
import torch

from league.config import load_config
from league.core.match_plan import MatchPlan
from league.core.players import Player
from league.rllib import bridge
from league.state.run_dir import run_differences
from ray.rllib.core.columns import Columns
from ray.rllib.evaluation.postprocessing import Postprocessing
from tests.training.test_same_seed import TINY_SMOKE, finish, iterations, killed_after_two_and_resumed, league

AHEAD = ["--set", "resources.sample_ahead=true", "--set", "resources.num_env_runners=2"]
TINY_AHEAD = [*TINY_SMOKE, *AHEAD]


@pytest.fixture(scope="module")
def whole_and_second(tmp_path_factory):
    """Two uninterrupted sample-ahead runs of the tiny smoke league, side by side."""
    base = tmp_path_factory.mktemp("sample_ahead")
    procs = [league(*TINY_AHEAD, "--run-dir", str(base / name)) for name in ("whole", "second")]
    for proc in procs:
        finish(proc)
    assert iterations(base / "whole") >= 4
    return base / "whole", base / "second"


def test_two_sample_ahead_runs_with_one_seed_are_one_run(whole_and_second):
    assert run_differences(*whole_and_second) == []


def test_a_sample_ahead_run_killed_and_resumed_is_the_run_never_killed(whole_and_second, tmp_path):
    whole, killed = whole_and_second[0], tmp_path / "killed"
    killed_after_two_and_resumed(TINY_AHEAD, whole, killed)  # past the first iteration: a batch waits in its checkpoint
    assert run_differences(whole, killed) == []


# ---------------------------------------------------------------- the lag, in one process
ATTACKER = Player(id=1, side="attacker", kind="learner", version=0, reward_method=2)
TEAM = Player(id=2, side="team", kind="scripted", version=0, scripted_targeter="avoid_attacker", scripted_defender="pure_pursuit")


@pytest.fixture(scope="module")
def algo_and_run(ray_instance):
    torch.set_num_threads(1)
    run = load_config("smoke", [
        "ppo.train_batch_size=512", "ppo.minibatch_size=256", "ppo.num_epochs=1", "resources.num_envs_per_env_runner=16",
        "resources.num_env_runners=1", "resources.sample_ahead=true",
    ])
    plan = MatchPlan([{"attacker": ATTACKER.name}], [[TEAM.modules()]], [[1.0]], seed=0)
    algo = bridge.build_config(run, [ATTACKER, TEAM], plan).build_algo()
    bridge.set_trainable(algo, [ATTACKER.name])
    yield algo, run
    algo.stop()


def sampled_by(run, weights: dict, batch: dict) -> bool:
    """Whether the policy with ``weights`` gives the batch's action distributions."""
    module = bridge.learner_spec(run, "attacker", 2).build()
    module.set_state(weights)
    module.eval()
    columns = batch[ATTACKER.name]
    with torch.no_grad():
        inputs = module.forward_inference({Columns.OBS: torch.from_numpy(columns[Columns.OBS])})[Columns.ACTION_DIST_INPUTS]
    return np.allclose(inputs.numpy(), columns[Columns.ACTION_DIST_INPUTS], atol=1e-5)


def test_each_batch_is_learned_one_update_after_the_policy_that_sampled_it(algo_and_run, monkeypatch):
    algo, run = algo_and_run
    learned = []  # the observations of each Learner update's batch
    update = algo.learner_group.update

    def recorded(*, batch, **kwargs):
        learned.append(batch.policy_batches[ATTACKER.name][Columns.OBS].copy())
        return update(batch=batch, **kwargs)

    monkeypatch.setattr(algo.learner_group, "update", recorded)
    weights = [bridge.learner_weights(algo, ATTACKER.name)]  # the learner's after each iteration
    waiting = [None]  # the batch waiting after each iteration
    for iteration in range(1, 5):
        bridge.begin_iteration(algo, run.seed, iteration)
        algo.train()
        weights.append(bridge.learner_weights(algo, ATTACKER.name))
        [part] = bridge.batch_sampled_ahead(algo)["parts"]
        waiting.append(part)
        # Batch k was sampled by the learner as it was after iteration k - 1 ...
        assert sampled_by(run, weights[iteration - 1], part), iteration
    # ... and learned in iteration k + 1, by the learner after iteration k: one update later.
    assert len(learned) == 3  # iteration 1 only samples
    for iteration, obs in enumerate(learned, start=2):
        assert np.array_equal(obs, waiting[iteration - 1][ATTACKER.name][Columns.OBS]), iteration
        if iteration >= 3:  # (after iteration 1 the learner is still the one that sampled)
            assert not sampled_by(run, weights[iteration - 1], waiting[iteration - 1]), iteration


def test_a_phase_end_drops_the_batch_sampled_ahead(algo_and_run):
    algo, run = algo_and_run
    assert bridge.batch_sampled_ahead(algo) is not None
    before = bridge.learner_weights(algo, ATTACKER.name)
    bridge.restart_games(algo)  # what the coordinator does when a phase ends
    bridge.begin_iteration(algo, run.seed, 5)
    algo.train()
    after = bridge.learner_weights(algo, ATTACKER.name)
    assert all(np.array_equal(before[key], after[key]) for key in before), "a batch of the old phase was learned"
    assert bridge.batch_sampled_ahead(algo) is not None  # the new phase's first batch waits



def test_a_batch_sampled_one_update_ago_is_clipped_around_the_learners_policy(algo_and_run, monkeypatch):
    # Decoupled PPO: the loss's "old" policy is the learner's as the update starts, not the one an update older
    # that sampled; each row's advantage weighted by their probability ratio (``ppo_loss.anchor_at_learner``).
    from league.rllib import learner as learner_module
    from league.rollout.train_batch import standardized

    algo, run = algo_and_run
    bridge.begin_iteration(algo, run.seed, 6)  # learns the batch the phase's end left (sampled by this very learner)
    algo.train()
    [waiting] = bridge.batch_sampled_ahead(algo)["parts"]  # sampled before the update above
    waiting = waiting[ATTACKER.name]
    seen = []
    original = learner_module.ppo_loss

    def recording(module, batch, c, bf16=False):
        if not seen:  # the first minibatch, before any gradient step: the learner as the update starts
            with torch.no_grad():
                seen.append((module.action_dist_inputs(batch[Columns.OBS]), {k: v.clone() for k, v in batch.items()}))
        return original(module, batch, c, bf16)

    monkeypatch.setattr(learner_module, "ppo_loss", recording)
    bridge.begin_iteration(algo, run.seed, 7)
    algo.train()
    [(learner_now, batch)] = seen
    rows = len(learner_now)  # the first minibatch: the batch's first rows (one epoch, no shuffle)
    assert np.array_equal(batch[Columns.OBS].numpy(), waiting[Columns.OBS][:rows])
    sampler = torch.from_numpy(waiting[Columns.ACTION_DIST_INPUTS][:rows])
    assert not torch.allclose(sampler, learner_now, atol=1e-4)  # the learner has moved since it sampled
    torch.testing.assert_close(batch[Columns.ACTION_DIST_INPUTS], learner_now)
    loc, log_std = learner_now.chunk(2, dim=-1)
    logp = torch.distributions.Normal(loc, log_std.exp()).log_prob(batch[Columns.ACTIONS]).sum(-1)
    # float32 log-densities of a few units: 1e-5 is a few ulps of their sum
    torch.testing.assert_close(batch[Columns.ACTION_LOGP], logp, atol=1e-5, rtol=0)
    weight = torch.exp(logp - torch.from_numpy(waiting[Columns.ACTION_LOGP][:rows]))
    advantages = torch.from_numpy(standardized(waiting[Postprocessing.ADVANTAGES]).astype(np.float32)[:rows])
    torch.testing.assert_close(batch[Postprocessing.ADVANTAGES], advantages * weight, atol=1e-5, rtol=1e-5)
