"""``LeaguePPO``: RLlib's PPO with its training step fed by the fast sampler's arrays."""

from __future__ import annotations

import logging
import math
from typing import Any

import numpy as np

from league.rollout.train_batch import standardized
from ray.rllib.algorithms.algorithm_config import AlgorithmConfig
from ray.rllib.algorithms.ppo import PPO
from ray.rllib.env.env_runner_group import EnvRunnerGroup
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


# RLlib logs each failed call to a lost env runner and its return at ERROR and WARNING, a
# dozen lines with Ray's error text; the run says what it lost and got back in one line each.
logging.getLogger("ray.rllib.utils.actor_manager").setLevel(logging.CRITICAL)

PING = "league_ping"  # the tag of the pings to lost env runners (`FaultTolerantPPO.restore_env_runners`)


def with_env_runner_fault_tolerance(config: AlgorithmConfig) -> AlgorithmConfig:
    """A lost env runner (its node died) neither stops the run nor holds up the others.

    Ray restarts it (``restart_failed_env_runners``) once a node with room for it joins; until
    then it is out of service and the others sample the whole batch. Before every training
    step RLlib's health probe pings the runners out of service and waits for all answers up to
    ``env_runner_health_probe_timeout_s`` (30 s by default): a runner whose node is gone
    answers with an error only after about 2 s, so every iteration after a loss took 2 s more
    (sampling 0.3 s -> 2.05 s in ``bench/node_loss.py``). 0 here: the probe only sends its
    pings, and ``FaultTolerantPPO.restore_env_runners`` brings a runner back once one of its
    pings has been answered.
    """
    return config.fault_tolerance(restart_failed_env_runners=True, env_runner_health_probe_timeout_s=0.0)


class FaultTolerantPPO(PPO):
    """RLlib's PPO with lost env runners brought back without holding up the others
    (``with_env_runner_fault_tolerance``)."""

    def restore_env_runners(self, env_runner_group: EnvRunnerGroup) -> list[int]:
        """RLlib's restore (state and weights sent to the runners back in service), with lost
        runners pinged without waiting: one ping in flight each, and a runner whose ping was
        answered since the last call is back in service (``with_env_runner_fault_tolerance``).
        A runner back gets the driver's current match plan, which ``set_match_plan`` sent the
        others before this iteration."""
        lost = sorted(set(range(1, env_runner_group.num_remote_env_runners() + 1)) - set(env_runner_group.healthy_env_runner_ids()))
        if lost:
            env_runner_group.fetch_ready_async_reqs(tags=PING, timeout_seconds=0.0, mark_healthy=True)
            env_runner_group.foreach_env_runner_async(lambda runner: runner.ping(), tag=PING, healthy_only=False, remote_worker_ids=lost)
        restored = super().restore_env_runners(env_runner_group)
        local = env_runner_group.local_env_runner
        if restored and local is not None:
            plan = local.config.policy_mapping_fn
            env_runner_group.foreach_env_runner(
                lambda runner: runner.config.multi_agent(policy_mapping_fn=plan), local_env_runner=False, remote_worker_ids=restored,
            )
        return restored


class LeaguePPO(FaultTolerantPPO):
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
