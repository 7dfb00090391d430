"""``LeaguePPO``: RLlib's PPO with its training step fed by the fast sampler's arrays."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from league.rollout.train_batch import standardized
from ray.rllib.algorithms.ppo import PPO
from ray.rllib.evaluation.postprocessing import Postprocessing
from ray.rllib.policy.sample_batch import MultiAgentBatch, SampleBatch
from ray.rllib.utils.metrics import (
    ALL_MODULES,
    ENV_RUNNER_RESULTS,
    ENV_RUNNER_SAMPLING_TIMER,
    LEARNER_RESULTS,
    LEARNER_UPDATE_TIMER,
    NUM_ENV_STEPS_SAMPLED,
    NUM_ENV_STEPS_SAMPLED_LIFETIME,
    NUM_MODULE_STEPS_TRAINED_LIFETIME,
    SYNCH_WORKER_WEIGHTS_TIMER,
    TIMERS,
)


class LeaguePPO(PPO):
    """PPO whose training step takes its data straight from the fast sampler's arrays.

    The same steps as ``PPO.training_step`` (sample, update the learner, sync the weights),
    with ``BatchedEnvRunner.sample_training_data`` in place of episodes and the learner
    connector pipeline: the batch reaches the Learner with its advantages and value targets.
    """

    def training_step(self) -> None:
        group, config = self.env_runner_group, self.config
        with self.metrics.log_time((TIMERS, ENV_RUNNER_SAMPLING_TIMER)):
            if group.num_remote_env_runners() == 0:
                sampled = [(self.env_runner.sample_training_data(config.total_train_batch_size), self.env_runner.get_metrics())]
            else:
                steps = math.ceil(config.total_train_batch_size / max(1, group.num_healthy_remote_env_runners()))
                sampled = group.foreach_env_runner(
                    lambda runner: (runner.worker_index, runner.sample_training_data(steps), runner.get_metrics()),
                    local_env_runner=False,
                    timeout_seconds=config.sample_timeout_s,
                )
                # In worker order, whichever answered first: the batch's row order is the Learner's.
                sampled = [(data, metrics) for _, data, metrics in sorted(sampled, key=lambda r: r[0])]
            if not sampled:
                return
            self.metrics.aggregate([metrics for _, metrics in sampled], key=ENV_RUNNER_RESULTS)
        env_steps = sum(int(metrics.get(NUM_ENV_STEPS_SAMPLED, 0)) for _, metrics in sampled)
        batch = training_batch([data for data, _ in sampled], env_steps)
        if batch is None:  # no trained module played
            return
        with self.metrics.log_time((TIMERS, LEARNER_UPDATE_TIMER)):
            learner_results = self.learner_group.update(
                batch=batch,
                timesteps={
                    NUM_ENV_STEPS_SAMPLED_LIFETIME: self.metrics.peek((ENV_RUNNER_RESULTS, NUM_ENV_STEPS_SAMPLED_LIFETIME)),
                    NUM_MODULE_STEPS_TRAINED_LIFETIME: self.metrics.peek(
                        (LEARNER_RESULTS, ALL_MODULES, NUM_MODULE_STEPS_TRAINED_LIFETIME), default=0
                    ),
                },
                num_epochs=config.num_epochs,
                minibatch_size=minibatch_size(config, batch),
                shuffle_batch_per_epoch=config.shuffle_batch_per_epoch,
            )
            self.metrics.aggregate(learner_results, key=LEARNER_RESULTS)
        with self.metrics.log_time((TIMERS, SYNCH_WORKER_WEIGHTS_TIMER)):
            group.sync_weights(
                from_worker_or_learner_group=self.learner_group,
                policies=set(learner_results[0]) - {ALL_MODULES},
                inference_only=True,
            )


MINIBATCH_SIZES = "league_minibatch_sizes"  # `learner_config_dict` key: learner module id -> rows per minibatch


def minibatch_size(config: Any, batch: MultiAgentBatch) -> int:
    """Rows per minibatch of the learners in ``batch`` (``PPOSettings.minibatch``); one side learns at a time."""
    by_module = config.learner_config_dict.get(MINIBATCH_SIZES, {})
    sizes = {by_module.get(module_id, config.minibatch_size) for module_id in batch.policy_batches}
    if len(sizes) != 1:
        raise ValueError(f"one update of learners with different minibatch sizes: {sorted(batch.policy_batches)}")
    return sizes.pop()


def training_batch(parts: list[dict[str, dict[str, np.ndarray]]], env_steps: int) -> MultiAgentBatch | None:
    """One ``MultiAgentBatch`` of the runners' data (``env_steps`` played), advantages standardised per module."""
    modules = sorted({module_id for part in parts for module_id in part})
    if not modules:
        return None
    batches = {}
    for module_id in modules:
        pieces = [part[module_id] for part in parts if module_id in part]
        columns = {key: np.concatenate([piece[key] for piece in pieces]) for key in pieces[0]}
        advantages = columns[Postprocessing.ADVANTAGES]
        columns[Postprocessing.ADVANTAGES] = standardized(advantages).astype(np.float32)
        batches[module_id] = SampleBatch(columns)
    return MultiAgentBatch(batches, env_steps=env_steps)
