"""``LeaguePPO``: RLlib's PPO with its training step fed by the fast sampler's arrays.

Sampling ahead (``resources.sample_ahead``, ``LeaguePPO.step_ahead``): the remote env runners
sample iteration k's batch while the driver's Learner updates on iteration k - 1's, so on two
cores one samples while the other learns (as APPO, with the lag fixed at one update). What the
lag means for the league:

* The league decides as before, once per iteration: iteration k's match plan, seeds and
  trainable set are the ones batch k is played under, and iteration k's ``train()`` result
  (outcomes, env steps, returns) is of batch k's games: the phase's counts, PFSP and the payoff
  see every game in the iteration it was played. Only the Learner runs one batch behind: the
  policy whose games iteration k counts is the learner after k - 2 updates, and a learning-curve
  point or a snapshot is of the learner that has not yet learned the last batch.
* The Learner clips each update around its own policy as the update starts, not around the
  policy one update older that sampled, and weights each row by their probability ratio
  (decoupled PPO, ``league.rllib.ppo_loss.anchor_at_learner``): with PPO's clip anchored at
  the sampler the learner had less room each update and learned less per env step
  (docs/results/time-to-strength.md, "Sampling ahead").
* A phase's end drops the batch sampled ahead (``bridge.restart_games``, with the games in
  flight): its games count for the phase that played them, but no learner learns from them,
  the old phase's learner (its snapshot is the learner as it is) nor the new phase's. A phase
  therefore learns from one batch fewer than it samples, and its first iteration only samples.
* A checkpoint keeps the batch sampled ahead (``league.training.checkpoints``), so that a
  resumed run learns from it in its next iteration as the run never stopped does: two runs of
  one seed are one run, and one killed and resumed is the run never killed
  (``tests/training/test_sample_ahead.py``).
* A lost remote runner's part of a batch is dropped, as without sampling ahead; the others
  sample the whole batch from the next iteration on (``FaultTolerantPPO``).
"""

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

    With ``resources.sample_ahead`` (``SAMPLE_AHEAD``) the remote runners sample this
    iteration's batch while the Learner updates on the last iteration's (``step_ahead``).
    """

    sampled_ahead: dict[str, Any] | None = None  # sample-ahead: the batch sampled last iteration, not yet learned
    trained_modules: set[str] = set()  # the modules of the last update (whose weights the runners need)

    def training_step(self) -> None:
        if self.config.learner_config_dict.get(SAMPLE_AHEAD):
            self.step_ahead()
            return
        with self.metrics.log_time((TIMERS, ENV_RUNNER_SAMPLING_TIMER)):
            sampled = self.sample()
            if not sampled:
                return
            self.metrics.aggregate([metrics for _, metrics in sampled], key=ENV_RUNNER_RESULTS)
        batch = self.batch_of(sampled)
        if batch is not None:  # (None: no trained module played)
            self.learn(batch)
            self.sync_weights()

    def step_ahead(self) -> None:
        """One iteration with sampling overlapped with learning, the lag fixed at one update.

        Iteration k: the remote runners start sampling batch k with the weights they hold (the
        Learner's after k - 2 updates); meanwhile the Learner updates on batch k - 1 (sampled
        in iteration k - 1 by the weights after k - 3 updates: one update old); once every
        runner has answered, the new weights go to the runners and batch k waits for iteration
        k + 1. The runners' weights change only between their samples, so the lag does not
        depend on which finishes first. An iteration without a batch waiting (the first, a
        phase's first: ``drop_sampled_ahead``) samples only.
        """
        group, config = self.env_runner_group, self.config
        tag = f"{SAMPLE_AHEAD}_{self.iteration}"  # a runner's late answer is never taken for a later iteration's
        launched = group.foreach_env_runner_async(self.remote_share(), tag=tag)
        waiting, self.sampled_ahead = self.sampled_ahead, None
        if waiting is not None:
            self.learn(training_batch(waiting["parts"], waiting["env_steps"]))
        with self.metrics.log_time((TIMERS, ENV_RUNNER_SAMPLING_TIMER)):
            answers = group.fetch_ready_async_reqs(tags=tag, timeout_seconds=config.sample_timeout_s) if launched else []
            sampled = [(data, metrics) for _, (_, data, metrics) in sorted(answers, key=lambda r: r[1][0])]
            if sampled:
                self.metrics.aggregate([metrics for _, metrics in sampled], key=ENV_RUNNER_RESULTS)
        if waiting is not None:
            self.sync_weights()
        if any(data for data, _ in sampled):  # a batch of a trained module
            self.sampled_ahead = {"parts": [data for data, _ in sampled], "env_steps": env_steps_of(sampled)}

    def drop_sampled_ahead(self) -> None:
        """Drop the batch sampled ahead (a phase's end: the next phase learns from its own games only)."""
        self.sampled_ahead = None

    def sample(self) -> list[tuple[dict[str, dict[str, np.ndarray]], dict[str, Any]]]:
        """Every runner's training data and metrics, in worker order (the order of the Learner's rows)."""
        group, config = self.env_runner_group, self.config
        if group.num_remote_env_runners() == 0:
            return [(self.env_runner.sample_training_data(config.total_train_batch_size), self.env_runner.get_metrics())]
        sampled = group.foreach_env_runner(self.remote_share(), local_env_runner=False, timeout_seconds=config.sample_timeout_s)
        # In worker order, whichever answered first: the batch's row order is the Learner's.
        return [(data, metrics) for _, data, metrics in sorted(sampled, key=lambda r: r[0])]

    def remote_share(self) -> Any:
        """The call that has one remote runner sample its share of the batch: ``(worker index, data, metrics)``."""
        steps = math.ceil(self.config.total_train_batch_size / max(1, self.env_runner_group.num_healthy_remote_env_runners()))
        return lambda runner: (runner.worker_index, runner.sample_training_data(steps), runner.get_metrics())

    @staticmethod
    def batch_of(sampled: list[tuple[dict[str, dict[str, np.ndarray]], dict[str, Any]]]) -> MultiAgentBatch | None:
        return training_batch([data for data, _ in sampled], env_steps_of(sampled))

    def learn(self, batch: MultiAgentBatch) -> None:
        """One update of the Learner on ``batch``."""
        config = self.config
        with self.metrics.log_time((TIMERS, LEARNER_UPDATE_TIMER)):
            learner_results = self.learner_group.update(
                batch=batch,
                timesteps={
                    NUM_ENV_STEPS_SAMPLED_LIFETIME: self.metrics.peek((ENV_RUNNER_RESULTS, NUM_ENV_STEPS_SAMPLED_LIFETIME)),
                    NUM_MODULE_STEPS_TRAINED_LIFETIME: self.metrics.peek(
                        (LEARNER_RESULTS, ALL_MODULES, NUM_MODULE_STEPS_TRAINED_LIFETIME), default=0
                    ),
                },
                num_epochs=learner_setting(config, batch, NUM_EPOCHS, config.num_epochs),
                minibatch_size=learner_setting(config, batch, MINIBATCH_SIZES, config.minibatch_size),
                shuffle_batch_per_epoch=config.shuffle_batch_per_epoch,
            )
            self.metrics.aggregate(learner_results, key=LEARNER_RESULTS)
        self.trained_modules = set(learner_results[0]) - {ALL_MODULES}

    def sync_weights(self) -> None:
        """The trained modules' new weights to the runners."""
        with self.metrics.log_time((TIMERS, SYNCH_WORKER_WEIGHTS_TIMER)):
            self.env_runner_group.sync_weights(
                from_worker_or_learner_group=self.learner_group, policies=self.trained_modules, inference_only=True,
            )


def env_steps_of(sampled: list[tuple[Any, dict[str, Any]]]) -> int:
    """Env steps the runners played for ``sampled`` (their metrics')."""
    return sum(int(metrics.get(NUM_ENV_STEPS_SAMPLED, 0)) for _, metrics in sampled)


MINIBATCH_SIZES = "league_minibatch_sizes"  # `learner_config_dict` key: learner module id -> rows per minibatch
NUM_EPOCHS = "league_num_epochs"  # `learner_config_dict` key: learner module id -> passes over its batch
SAMPLE_AHEAD = "league_sample_ahead"  # `learner_config_dict` key: `resources.sample_ahead`
COMPILED_LOSS = "league_compiled_loss"  # `learner_config_dict` key: `ppo.compile_loss`, where torch can compile
RESIDUAL_PENALTIES = "league_residual_penalties"  # `learner_config_dict` key: learner module id -> `ppo.attacker_residual_penalty`
RESIDUAL_PENALTY_GATED = "league_residual_penalty_gated"  # `learner_config_dict` key: `ppo.attacker_residual_penalty_gate` not `always`


def learner_setting(config: Any, batch: MultiAgentBatch, key: str, default: int) -> int:
    """The learners' value of a per-module setting (``MINIBATCH_SIZES``, ``NUM_EPOCHS``) for the learners in
    ``batch``, ``default`` for a module without one; one side learns at a time."""
    by_module = config.learner_config_dict.get(key, {})
    values = {by_module.get(module_id, default) for module_id in batch.policy_batches}
    if len(values) != 1:
        raise ValueError(f"one update of learners with different {key}: {sorted(batch.policy_batches)}")
    return values.pop()


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
