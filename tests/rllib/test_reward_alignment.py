"""The reward of a step reaches the action that earned it, on every sampler.

The attacker module trains on reward method 3 while the env's own attacker reward is
method 1, so its reward must come from the per-method rewards: on the fast path from the
sampler's arrays (``league.rllib.env_runner``), on the batched and standard paths from
the episodes' infos through the reward connector (``AttackerRewardByMethod``). The
oracle is the core itself: every call of ``BatchedGame.step`` is logged, keyed by the
attacker's action (a float32 Gaussian sample: unique), with A's method-3 reward of that
step. Each training row of the attacker must carry exactly the reward logged for its
action.
"""

import numpy as np
import pytest
import torch

from envs.core import BatchedGame
from league.config import RunConfig
from league.core.players import Player
from league.core.match_plan import MatchPlan
from league.rllib.bridge import build_config, set_trainable
from ray.rllib.connectors.learner import AddOneTsToEpisodesAndTruncate
from ray.rllib.core.columns import Columns
from ray.rllib.evaluation.postprocessing import Postprocessing

GAMES = 4
METHOD = 3  # the attacker module's reward method
ENV_METHOD = 1  # the env's configured attacker reward (what `rewards` carries)
# A discount of ~0 and lambda 0 make the fast path's value target of a row its reward
# (plus 1e-9 times a value of size < 10: below 1e-8, far below any reward here).
GAMMA = 1e-9
ATTACKER = Player(id=1, side="attacker", kind="learner", version=0, reward_method=METHOD)
TEAM = Player(id=2, side="team", kind="learner", version=0)
SCRIPTED_TEAM = Player(
    id=3, side="team", kind="scripted", version=0, scripted_targeter="avoid_attacker", scripted_defender="pure_pursuit"
)


class CoreLog:
    """A's rewards of every core step, by the bytes of the attacker's float32 action."""

    def __init__(self):
        self.rewards: dict[bytes, np.ndarray] = {}

    def install(self, monkeypatch):
        original = BatchedGame.step
        log = self.rewards

        def step(game, actions):
            running = game.active.copy()
            result = original(game, actions)
            attacker_actions = np.asarray(actions)[:, 0].astype(np.float32)  # the sampler's float32, widened exactly
            for g in np.flatnonzero(running):
                key = attacker_actions[g].tobytes()
                assert key not in log, "two steps with the same attacker action: the key is not unique"
                log[key] = result.attacker_rewards[g].copy()
            return result

        monkeypatch.setattr(BatchedGame, "step", step)


def build(sampler):
    run = RunConfig(
        name="alignment",
        seed=11,
        game={"attacker_reward": ENV_METHOD, "terminal_reward": 5.0},
        ppo={"train_batch_size": 200, "minibatch_size": 100, "num_epochs": 1, "hidden": [16], "gamma": GAMMA, "lambda_": 0.0},
        resources={"num_envs_per_env_runner": GAMES, "sampler": sampler},
    )
    plan = MatchPlan([{"attacker": ATTACKER.name}], [[SCRIPTED_TEAM.modules()]], [[1.0]], seed=0)
    algo = build_config(run, [ATTACKER, TEAM, SCRIPTED_TEAM], plan).build_algo()
    set_trainable(algo, [ATTACKER.name])
    return algo


def check_rows(actions: np.ndarray, rewards: np.ndarray, log: CoreLog, atol: float) -> None:
    expected = np.array([log.rewards[a.tobytes()][METHOD - 1] for a in actions.astype(np.float32)])
    env_reward = np.array([log.rewards[a.tobytes()][ENV_METHOD - 1] for a in actions.astype(np.float32)])
    assert len(expected) >= 150
    # The test can fail: a row's reward differs from the env's configured one, and from other steps' rewards.
    assert np.mean(expected != env_reward) > 0.5
    assert len(np.unique(expected)) > 0.5 * len(expected)
    assert np.any(np.abs(expected) >= 5.0)  # game ends with the terminal reward among them
    # float32 rows of float64 rewards: within one float32 ulp (2**-23 relative).
    np.testing.assert_allclose(rewards, expected, rtol=2**-23, atol=atol)


def test_fast_path_rows_carry_the_reward_of_their_own_step(ray_instance, monkeypatch):
    log = CoreLog()
    log.install(monkeypatch)
    algo = build("fast")
    try:
        runner = algo.env_runner
        actions, targets = [], []
        for _ in range(3):  # games continue across calls
            data = runner.sample_training_data(GAMES * 20)[ATTACKER.name]
            actions.append(data[Columns.ACTIONS])
            targets.append(data[Postprocessing.VALUE_TARGETS])
    finally:
        algo.stop()
    check_rows(np.concatenate(actions), np.concatenate(targets), log, atol=1e-8)


@pytest.mark.parametrize("sampler", ["batched", "standard"])
def test_episode_paths_pay_the_reward_of_its_own_step_through_the_connector(ray_instance, monkeypatch, sampler):
    log = CoreLog()
    log.install(monkeypatch)
    algo = build(sampler)
    try:
        episodes = []
        for _ in range(3):  # chunks of episodes that continue in the next call
            episodes += algo.env_runner.sample(num_timesteps=GAMES * 20, explore=True)
        assert any(e.is_done for e in episodes) and any(not e.is_done for e in episodes)

        def connector_batch(learner):
            # As PPO's Learner builds it (`PPOLearner.build`): the one-timestep extension first.
            pipeline = learner.config.build_learner_connector(None, None)
            pipeline.prepend(AddOneTsToEpisodesAndTruncate())
            batch = pipeline(rl_module=learner.module, batch={}, episodes=episodes, shared_data={})[ATTACKER.name]
            return {k: np.asarray(v.detach() if torch.is_tensor(v) else v) for k, v in batch.items()}

        [call] = algo.learner_group.foreach_learner(connector_batch)
        batch = call.get()
    finally:
        algo.stop()
    real = batch[Columns.LOSS_MASK].astype(bool)  # without the appended bootstrap step of each chunk
    check_rows(batch[Columns.ACTIONS][real], batch[Columns.REWARDS][real], log, atol=0.0)
