"""Where the league meets RLlib: algorithm config, modules, mapping, results, checkpoints.

(Besides this module, RLlib is imported by the fast sampler, ``league.rllib.env_runner``,
the RLModules, ``league.rllib.modules``, and ``league.rllib.compat``, the one module that
touches RLlib's private attributes and episode internals. Checkpoints are loaded and
``train()`` results read only here.)

* ``MatchPlan`` is the agent-to-module mapping. It decides each episode's opponent
  once, from the episode id and a seed (the same match whoever asks, whenever), by the PFSP
  probabilities the coordinator computed; it is a picklable object sent to every
  EnvRunner.
* ``OutcomeRecorder`` logs, per finished episode, which modules played and the outcome;
  the counts reach the driver through RLlib's metrics (summed over the iteration).
"""

from __future__ import annotations

import functools
import logging
import math
import random
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from envs.agents import AGENTS
from envs.observations import observation_size
from envs.rllib_env import TargetDefenseMultiAgentEnv, policy_input_space
from envs.single import action_space
from league.rllib.env_runner import OUTCOMES_KEY, SEPARATOR, BatchedEnvRunner, log_outcome, seed_iteration
from league.rllib import compat
from league.config import RunConfig
from league.rllib.flat_adam import FlatAdam
from league.rllib.modules import ActorCriticModule, ScriptedModule
from league.rllib.ppo_loss import LossRows, PPOCoefficients, loss_stats, ppo_loss
from league.core.players import Player
from league.rollout.train_batch import minibatch_rows, standardized
from ray.rllib.algorithms.algorithm import Algorithm
from ray.rllib.algorithms.ppo import PPO, PPOConfig
from ray.rllib.algorithms.ppo.torch.ppo_torch_learner import PPOTorchLearner
from ray.rllib.callbacks.callbacks import RLlibCallback
from ray.rllib.connectors.connector_v2 import ConnectorV2
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec
from ray.rllib.env.multi_agent_env_runner import MultiAgentEnvRunner
from ray.rllib.evaluation.postprocessing import Postprocessing
from ray.rllib.policy.sample_batch import MultiAgentBatch, SampleBatch
from ray.rllib.utils.metrics import (
    ALL_MODULES,
    ENV_RUNNER_RESULTS,
    ENV_RUNNER_SAMPLING_TIMER,
    EPISODE_MODULE_RETURN_MEAN,
    LEARNER_RESULTS,
    LEARNER_UPDATE_TIMER,
    NUM_ENV_STEPS_SAMPLED,
    NUM_ENV_STEPS_SAMPLED_LIFETIME,
    NUM_MODULE_STEPS_SAMPLED,
    NUM_MODULE_STEPS_TRAINED_LIFETIME,
    SYNCH_WORKER_WEIGHTS_TIMER,
    TIMERS,
)



class _NotTheNews(logging.Filter):
    """Drops RLlib's banner on every config built ("You are running PPO on the new API stack!")."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "on the new API stack" not in record.getMessage()


logging.getLogger("ray.rllib.algorithms.algorithm_config").addFilter(_NotTheNews())
# RLlib registers the env with gymnasium anew for every algorithm built; gymnasium then warns, in colour.
warnings.filterwarnings("ignore", message=r".*Overriding environment .* already in registry")


def env_config(run: RunConfig) -> dict[str, Any]:
    return {**run.game.model_dump(), "with_global_state": True}


def actor_inputs(run: RunConfig, agent: str) -> int:
    """Length of the agent's own observation (the global state follows it)."""
    return observation_size(run.game, AGENTS.index(agent))


def learner_spec(run: RunConfig, side: str, reward_method: int | None = None) -> RLModuleSpec:
    agent = "attacker" if side == "attacker" else "targeter"
    gamma, lambda_ = run.ppo.discount(side)
    return RLModuleSpec(
        module_class=ActorCriticModule,
        observation_space=policy_input_space(run.game, agent),
        action_space=action_space(run.game),
        model_config={
            "actor_inputs": actor_inputs(run, agent),
            "critic": "local" if side == "attacker" else "global",
            "hidden": run.ppo.hidden,
            "reward_method": reward_method,
            # The fast sampler's GAE reads them per module (the team's may differ: `PPOSettings.team_gamma`).
            "gamma": gamma,
            "lambda_": lambda_,
            "targeter_shaping": run.ppo.targeter_shaping if side == "team" else 0.0,
            "team_reward": run.ppo.team_reward if side == "team" else "own",
            "explore_when_frozen": run.league.frozen_players_explore,  # read by the fast sampler
        },
    )


def scripted_spec(run: RunConfig, agent: str, name: str) -> RLModuleSpec:
    return RLModuleSpec(
        module_class=ScriptedModule,
        observation_space=policy_input_space(run.game, agent),
        action_space=action_space(run.game),
        model_config={"agent": agent, "name": name, "game": run.game.model_dump(), "actor_inputs": actor_inputs(run, agent)},
    )


def player_specs(run: RunConfig, player: Player) -> dict[str, RLModuleSpec]:
    """Module id -> spec of every module the player needs."""
    if player.kind != "scripted":
        return {player.name: learner_spec(run, player.side, player.reward_method)}
    return {module: scripted_spec(run, agent, module.split("-", 2)[2]) for agent, module in player.modules().items()}


def _draw(seed: int, episode_id: str, salt: str, weights: list[float]) -> int:
    """Index drawn with ``weights``, fixed by (seed, episode, salt): no state between calls."""
    if len(weights) == 1:  # the only index, whatever the draw (seeding the generator costs more than the rest)
        return 0
    cumulative = np.cumsum(weights)
    draw = random.Random(f"{seed}:{episode_id}:{salt}").random() * cumulative[-1]
    return int(min(np.searchsorted(cumulative, draw, side="right"), len(weights) - 1))


@dataclass
class MatchPlan:
    """Agent -> module mapping for one phase.

    Each episode draws one of the side's ``learners`` (uniformly; the coordinator lists the
    side's exploiters among them, so each gets a learner's share of the games), then that
    learner's opponent with its ``probabilities`` (PFSP, or uniform over an exploiter's
    targets); both draws depend only on the seed and the episode id, so every agent of an
    episode gets the same match.
    """

    learners: list[dict[str, str]]
    opponents: list[list[dict[str, str]]]
    probabilities: list[list[float]]
    seed: int
    # The last episode's match: its three agents ask one after the other.
    _last: tuple[str, dict[str, str]] = field(default=("", {}), repr=False, compare=False)

    def match(self, episode_id: str) -> dict[str, str]:
        if self._last[0] != episode_id:
            k = _draw(self.seed, episode_id, "learner", [1.0] * len(self.learners))
            opponent = self.opponents[k][_draw(self.seed, episode_id, "opponent", self.probabilities[k])]
            self._last = (episode_id, {**self.learners[k], **opponent})
        return self._last[1]

    def __call__(self, agent_id: str, episode: Any = None, **kwargs: Any) -> str:
        return self.match(episode.id_)[agent_id]


class AttackerRewardByMethod(ConnectorV2):
    """Learner connector: pays each attacker module the reward of its own method.

    The env reports A's reward under all three methods in its info
    (``attacker_rewards``); this lets attackers of different methods share one league.
    It runs after PPO's one-timestep extension, whose phantom last reward stays as is.
    """

    def __call__(self, *, rl_module: Any, batch: dict[str, Any], episodes: list[Any], **kwargs: Any) -> Any:
        for episode in episodes:
            attacker = episode.agent_episodes.get("attacker")
            module_id = episode.module_for("attacker")
            if attacker is None or module_id not in rl_module:
                continue
            method = (rl_module[module_id].model_config or {}).get("reward_method")
            real_steps = len(attacker) - 1  # the last step is PPO's phantom bootstrap step
            if not method or real_steps <= 0:
                continue
            infos = attacker.get_infos(slice(1, real_steps + 1))
            compat.overwrite_rewards(attacker, [info["attacker_rewards"][method - 1] for info in infos])
        return batch


class OutcomeRecorder(RLlibCallback):
    """Counts finished episodes by (attacker module, targeter module, defender module, outcome)."""

    def on_episode_end(self, *, episode, metrics_logger=None, **kwargs) -> None:
        # Every agent's last info names the outcome (the batched sampler keeps only the learners').
        outcome = next(iter(episode.agent_episodes.values())).get_infos(-1)["outcome"]
        log_outcome(metrics_logger, [episode.module_for(agent) for agent in AGENTS], outcome)


def episode_outcomes(result: dict[str, Any]) -> list[tuple[tuple[str, str, str], str, int]]:
    """``((attacker, targeter, defender modules), outcome, count)`` of one ``train()`` result."""
    counts = result.get(ENV_RUNNER_RESULTS, {}).get(OUTCOMES_KEY, {})
    rows = []
    for modules, outcomes in counts.items():
        for outcome, count in outcomes.items():
            if count == count and count > 0:  # keys of modules that did not play this time are NaN
                rows.append((tuple(modules.split(SEPARATOR)), outcome, int(count)))
    return rows


def module_returns(result: dict[str, Any], modules: list[str]) -> dict[str, float]:
    """Mean episode return of each of ``modules`` that finished episodes this iteration."""
    means = result.get(ENV_RUNNER_RESULTS, {}).get(EPISODE_MODULE_RETURN_MEAN, {})
    return {m: float(means[m]) for m in modules if m in means and means[m] == means[m]}


def env_runner_health(algo: Algorithm) -> tuple[int, int, int]:
    """``(healthy, total, restarts)`` of the remote env runners (all 0 when sampling in the driver)."""
    group = algo.env_runner_group
    return group.num_healthy_remote_env_runners(), group.num_remote_env_runners(), group.num_remote_worker_restarts()


def sampled_env_steps(result: dict[str, Any]) -> int:
    return int(result.get(ENV_RUNNER_RESULTS, {}).get(NUM_ENV_STEPS_SAMPLED_LIFETIME, 0))


def learner_env_steps(result: dict[str, Any], learners: list[Player]) -> dict[str, int]:
    """Env steps of the games each learner played in this ``train()``, from the runners' exact
    per-module counts: a module's agent steps over the agents it plays in a game (the team's
    module plays T and D)."""
    played = result.get(ENV_RUNNER_RESULTS, {}).get(NUM_MODULE_STEPS_SAMPLED, {})
    steps = {}
    for learner in learners:
        count = played.get(learner.name, 0)
        steps[learner.name] = int(count) // len(learner.modules()) if count == count else 0  # NaN: idle this time
    return steps


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


def _runner_threads(threads: int, env_runner: Any = None, **kwargs: Any) -> None:
    """``on_environment_created`` callback: the torch threads of an env runner's process
    (RLlib leaves torch's default, all cores)."""
    torch.set_num_threads(threads)


@dataclass
class ClippedStep:
    """One optimizer of a module in ``LeaguePPOLearner``'s update: its gradients clipped by
    global norm (``grad_clip``: the module's config), then stepped (as one buffer by ``flat``)."""

    module_id: str
    grad_clip: float | None
    name: str
    optimizer: Any
    flat: FlatAdam | None


def release(steps: list[ClippedStep] | None) -> None:
    for step in steps or ():
        if step.flat:
            step.flat.release()


class LeaguePPOLearner(PPOTorchLearner):
    """PPO learner that gives no optimizer to parameter-free (scripted) modules, and that
    updates from a ready batch (the fast sampler's) in plain torch.

    ``update`` of a ``MultiAgentBatch`` (one local Learner; every module to train an
    ``ActorCriticModule`` with a critic, its batch without a loss mask) takes the gradient
    steps of RLlib's ``Learner.update`` (Ray 2.60) and reports its results: the same
    minibatches in the same order (``train_batch.minibatch_rows``, drawing RLlib's shuffles
    from NumPy's global generator), RLlib's PPO loss operation for operation
    (``league.rllib.ppo_loss``), the same backward pass, clipping by global norm and Adam step,
    the same steps counted, then RLlib's ``after_gradient_based_update`` (lr, entropy and KL
    coefficients). ``tests/test_fast_path.py`` checks the weights equal to the bit and the
    results equal to RLlib's update. Cheaper:

    * a minibatch is one ``index_select`` of the loss's columns side by side
      (``ppo_loss.LossRows``), not the whole batch shuffled column by column (in place:
      RLlib's update reorders the caller's batch) and sliced into ``SampleBatch`` copies;
    * the loss without RLlib's distribution objects, forward wrappers and per-minibatch
      metrics: RLlib logs the loss statistics with window 1, so only the last minibatch's
      are reported (and read by the KL coefficient's update): they are computed for the last
      minibatch only, and the steps trained are counted once per update;
    * finite gradients (their global norm is) are clipped in one foreach multiply with
      RLlib's coefficient, ``max / max(norm + 1e-6, max)``, and stepped by Adam as one buffer
      per module (``flat_adam.FlatAdam``, the same arithmetic); RLlib's
      ``postprocess_gradients`` and ``apply_gradients`` go tensor by tensor, with two
      finiteness checks each. Non-finite gradients take RLlib's own two steps.

    One result differs: RLlib logs a gradient norm of 0.0 for every module with an
    optimizer that was not in the update; this logs norms of trained modules only. Episodes
    (the standard sampler), several Learners and other modules take RLlib's ``update``.
    (``build_config`` sets no ``torch.compile``, grad scaler or torch lr scheduler, which
    this update does not know.)

    It also clocks its own updates: RLlib's ``learner_update_timer`` is an exponential
    average over iterations (coefficient 0.01), so it mostly repeats the first iteration.
    """

    update_seconds = 0.0  # wall time of ``update`` calls since the last ``take_update_seconds``

    KL_COEFFS_KEY = "league_kl_coeffs"

    # PPO's adaptive KL coefficients are part of the Learner's state here: RLlib's (Ray 2.60)
    # leaves them out, so a resumed run would restart them at `kl_coeff` and train otherwise.
    def get_state(self, components: Any = None, *, not_components: Any = None, **kwargs: Any) -> dict[str, Any]:
        state = super().get_state(components, not_components=not_components, **kwargs)
        state[self.KL_COEFFS_KEY] = {m: float(c) for m, c in self.curr_kl_coeffs_per_module.items()}
        return state

    def set_state(self, state: dict[str, Any]) -> None:
        super().set_state(state)
        for module_id, coeff in state.get(self.KL_COEFFS_KEY, {}).items():
            self.curr_kl_coeffs_per_module[module_id].data.fill_(coeff)

    def configure_optimizers_for_module(self, module_id: str, config: Any = None) -> None:
        """RLlib's Adam (``TorchLearner``'s), stepping all tensors in foreach passes (the
        same arithmetic as its default per-tensor loop on CPU)."""
        params = list(self.module[module_id].parameters())
        if params:
            optimizer = torch.optim.Adam(params, foreach=True)
            self.register_optimizer(
                module_id=module_id, optimizer=optimizer, params=params, lr_or_lr_schedule=config.lr
            )
            for group in optimizer.param_groups:  # a schedule's first rate is a tensor, which foreach Adam refuses
                group["lr"] = float(group["lr"])

    def update(
        self,
        batch: MultiAgentBatch | None = None,
        *,
        training_data: Any = None,
        timesteps: dict[str, Any] | None = None,
        num_epochs: int = 1,
        minibatch_size: int | None = None,
        shuffle_batch_per_epoch: bool = False,
        **kwargs: Any,
    ) -> Any:
        started = time.perf_counter()
        try:
            ready = batch if training_data is None else training_data.batch  # the LearnerGroup sends `training_data`
            if isinstance(ready, MultiAgentBatch) and minibatch_size and not kwargs and self._has_own_loss(ready):
                return self._update_in_minibatches(
                    ready, timesteps or {}, num_epochs, minibatch_size, shuffle_batch_per_epoch and num_epochs > 1
                )
            return super().update(
                batch=batch, training_data=training_data, timesteps=timesteps, num_epochs=num_epochs,
                minibatch_size=minibatch_size, shuffle_batch_per_epoch=shuffle_batch_per_epoch, **kwargs,
            )
        finally:
            self.update_seconds += time.perf_counter() - started

    def _has_own_loss(self, batch: MultiAgentBatch) -> bool:
        """Whether the learner's own update applies: one local Learner, and every module to
        update an ``ActorCriticModule`` with a critic, its batch without a loss mask."""
        if self.config.num_learners > 1:
            return False
        for module_id, module_batch in batch.policy_batches.items():
            if self.should_module_be_updated(module_id, batch):
                config = self.config.get_config_for_module(module_id)
                own = isinstance(self.module[module_id], ActorCriticModule) and config.use_critic
                if not own or Columns.LOSS_MASK in module_batch:
                    return False
        return True

    def _update_in_minibatches(
        self, batch: MultiAgentBatch, timesteps: dict[str, Any], num_epochs: int, minibatch_size: int, shuffle: bool
    ) -> dict[str, Any]:
        self.before_gradient_based_update(timesteps=timesteps)
        compat.count_weights_update(self)
        modules = [m for m in batch.policy_batches if self.should_module_be_updated(m, batch)]
        inputs = {m: LossRows(batch.policy_batches[m], self.device) for m in modules}
        coefficients = {m: self._ppo_coefficients(m) for m in modules}
        trained = [p for m in modules for _, o in self.get_optimizers_for_module(m) for g in o.param_groups for p in g["params"]]
        for m in modules:
            self.module[m].train()  # as RLlib's forward_train
        # RLlib sets every optimizer's gradients to None before each backward pass: here all
        # once (modules outside the loss keep None), then the trained modules' each time.
        for module_id in self.module.keys():
            for _, optimizer in self.get_optimizers_for_module(module_id):
                optimizer.zero_grad(set_to_none=True)
        minibatches = list(minibatch_rows({m: inputs[m].length for m in modules}, minibatch_size, num_epochs, shuffle))
        loss_per_module: dict[str, torch.Tensor] = {}
        steps = self._clipped_steps(modules)
        try:
            for n, rows in enumerate(minibatches, start=1):
                last = n == len(minibatches)  # RLlib's statistics keep the last minibatch's only (window 1)
                for m in modules:
                    loss_per_module[m], terms = ppo_loss(self.module[m], inputs[m].take(rows[m]), coefficients[m])
                    if last:
                        self.metrics.log_dict(loss_stats(terms), key=m, window=1)
                for p in trained:
                    p.grad = None
                sum(loss_per_module.values()).backward()
                if steps is None or not self._clip_and_step(steps, log_norms=last):
                    release(steps)  # RLlib's steps go parameter by parameter
                    self.apply_gradients(self.postprocess_gradients(compat.gradients(self)))
                    steps = self._clipped_steps(modules)
        finally:
            release(steps)
        compat.log_trained_minibatches(self, dict.fromkeys(modules, minibatch_size), batch.env_steps(), len(minibatches))
        for module_id, loss in loss_per_module.items():  # as RLlib: the last minibatch's
            self.metrics.log_value(key=(module_id, self.TOTAL_LOSS_KEY), value=loss, window=1)
        self.after_gradient_based_update(timesteps=timesteps)
        return self.metrics.reduce()

    def _ppo_coefficients(self, module_id: str) -> PPOCoefficients:
        """The module's loss settings for this update: the entropy coefficient is stepped by
        its scheduler and the KL coefficient adapted after an update, not during one."""
        config = self.config.get_config_for_module(module_id)
        return PPOCoefficients(
            clip_param=config.clip_param,
            vf_clip_param=config.vf_clip_param,
            vf_loss_coeff=config.vf_loss_coeff,
            entropy_coeff=self.entropy_coeff_schedulers_per_module[module_id].get_current_value(),
            kl_coeff=self.curr_kl_coeffs_per_module[module_id] if config.use_kl_loss else None,
        )

    def _clipped_steps(self, module_ids: list[str]) -> list[ClippedStep] | None:
        """Every optimizer of ``module_ids``, its tensors made one buffer where ``FlatAdam``
        applies (``release`` undoes it), if every module clips by global norm without logging
        gradients (what ``_clip_and_step`` does); else None."""
        steps = []
        for module_id in module_ids:
            config = self.config.get_config_for_module(module_id)
            if config.grad_clip_by != "global_norm" or config.log_gradients:
                release(steps)
                return None
            for name, optimizer in self.get_optimizers_for_module(module_id):
                flat = FlatAdam(optimizer) if FlatAdam.applies(optimizer) else None
                steps.append(ClippedStep(module_id, config.grad_clip, name, optimizer, flat))
        return steps

    def _clip_and_step(self, steps: list[ClippedStep], log_norms: bool) -> bool:
        """Clip the gradients of each of ``steps``' optimizers by their global norm and step
        it, logging the norm if ``log_norms``, as RLlib's postprocessing does; nothing (False)
        unless every parameter has a gradient and every norm is finite."""
        norms = []
        for step in steps:
            params = [p for group in step.optimizer.param_groups for p in group["params"]]
            if any(p.grad is None for p in params):  # (Adam would pass over them)
                return False
            norm = torch.nn.utils.get_total_norm([p.grad for p in params], foreach=True)
            if not torch.isfinite(norm):
                return False
            norms.append((params, norm))
        for step, (params, norm) in zip(steps, norms):
            if step.flat:
                step.flat.gather_gradients()
                params = step.flat.parameters
            if step.grad_clip:
                torch.nn.utils.clip_grads_with_norm_(params, step.grad_clip, norm, foreach=True)
                if log_norms:
                    self.metrics.log_value(key=(step.module_id, f"gradients_{step.name}_global_norm"), value=norm, window=1)
            if step.flat:
                step.flat.step()
            else:
                step.optimizer.step()
        return True

    def take_update_seconds(self) -> float:
        seconds, self.update_seconds = self.update_seconds, 0.0
        return seconds


def take_learning_seconds(algo: Algorithm) -> float:
    """Wall time the Learner spent updating since the last call (the slowest Learner's, if several)."""
    results = algo.learner_group.foreach_learner(lambda learner: learner.take_update_seconds())
    return max((r.get() for r in results if r.ok), default=0.0)


def build_config(run: RunConfig, players: list[Player], plan: MatchPlan) -> PPOConfig:
    """PPO over every module the ``players`` need; only learners are ever trained."""
    specs: dict[str, RLModuleSpec] = {}
    for player in players:
        specs.update(player_specs(run, player))
    res, ppo = run.resources, run.ppo
    return (
        PPOConfig(algo_class=LeaguePPO if res.sampler == "fast" else PPO)
        .environment(env=TargetDefenseMultiAgentEnv, env_config=env_config(run), normalize_actions=False, clip_actions=False)
        .env_runners(
            num_env_runners=res.num_env_runners,
            num_envs_per_env_runner=res.num_envs_per_env_runner,
            num_cpus_per_env_runner=res.num_cpus_per_env_runner,
            custom_resources_per_env_runner=res.custom_resources_per_env_runner,
            rollout_fragment_length="auto",
            env_runner_cls=MultiAgentEnvRunner if res.sampler == "standard" else BatchedEnvRunner,
        )
        .learners(
            num_learners=0,
            learner_config_dict={
                MINIBATCH_SIZES: {p.name: ppo.minibatch(p.side) for p in players if p.trains}
            },
        )
        .multi_agent(
            policies=list(specs),
            policy_mapping_fn=plan,
            policies_to_train=[p.name for p in players if p.trains],
        )
        .rl_module(rl_module_spec=MultiRLModuleSpec(rl_module_specs=specs))
        .training(
            lr=ppo.lr if ppo.lr_schedule is None else [list(point) for point in ppo.lr_schedule],
            gamma=ppo.gamma,
            lambda_=ppo.lambda_,
            clip_param=ppo.clip_param,
            entropy_coeff=ppo.entropy_coeff,
            vf_loss_coeff=ppo.vf_loss_coeff,
            grad_clip=ppo.grad_clip,
            train_batch_size_per_learner=ppo.train_batch_size,
            minibatch_size=ppo.minibatch_size,
            num_epochs=ppo.num_epochs,
            vf_clip_param=float("inf"),
            learner_class=LeaguePPOLearner,
            learner_connector=lambda observation_space, action_space: AttackerRewardByMethod(),
        )
        .fault_tolerance(restart_failed_env_runners=True)
        .callbacks(
            OutcomeRecorder,
            on_environment_created=functools.partial(_runner_threads, res.threads_for(res.num_cpus_per_env_runner)),
        )
        .debugging(seed=run.seed, log_level="ERROR")
        .reporting(metrics_num_episodes_for_smoothing=100)
    )


def set_match_plan(algo: Algorithm, plan: MatchPlan) -> None:
    """Send a new mapping to every EnvRunner (ongoing episodes keep their old mapping)."""
    algo.env_runner_group.foreach_env_runner(
        lambda runner: runner.config.multi_agent(policy_mapping_fn=plan), local_env_runner=True
    )


def begin_iteration(algo: Algorithm, seed: int, iteration: int) -> None:
    """Seed every env runner's (and the driver's) generators for ``iteration`` of a run seeded
    ``seed`` (``BatchedEnvRunner.begin_iteration``): an iteration then depends only on the
    checkpointed state it starts from, not on how the process got there."""

    def begin(runner: Any) -> None:
        if isinstance(runner, BatchedEnvRunner):
            runner.begin_iteration(seed, iteration)
        else:  # RLlib's own runner (`sampler: standard`) names its episodes at random all the same
            seed_iteration(runner, seed, iteration)

    algo.env_runner_group.foreach_env_runner(begin, local_env_runner=True)


def games_in_flight(algo: Algorithm) -> dict[int, bytes]:
    """Each fast or batched env runner's games in flight (``BatchedEnvRunner.games_in_flight``), by worker index."""
    states = algo.env_runner_group.foreach_env_runner(
        lambda runner: (runner.worker_index, runner.games_in_flight()) if isinstance(runner, BatchedEnvRunner) else None,
        local_env_runner=True,
    )
    return dict(state for state in states if state is not None)


def restart_games(algo: Algorithm) -> None:
    """Every fast or batched env runner drops its games in flight (``BatchedEnvRunner.restart_games``)."""
    _on_batched_runners(algo, lambda runner: runner.restart_games())


def _on_batched_runners(algo: Algorithm, call: Any) -> None:
    """``call(runner)`` on every fast or batched env runner, the driver's included."""
    algo.env_runner_group.foreach_env_runner(
        lambda runner: call(runner) if isinstance(runner, BatchedEnvRunner) else None, local_env_runner=True
    )


def restore_games(algo: Algorithm, states: dict[int, bytes]) -> None:
    """Hand each env runner its games in flight from ``games_in_flight`` (a runner without any starts anew)."""

    _on_batched_runners(
        algo, lambda runner: runner.restore_games(states[runner.worker_index]) if runner.worker_index in states else None
    )


def set_trainable(algo: Algorithm, module_ids: list[str]) -> None:
    """Train only ``module_ids`` from now on (the learning side of the phase)."""
    algo.learner_group.foreach_learner(lambda learner: learner.config.multi_agent(policies_to_train=module_ids))
    algo.env_runner_group.foreach_env_runner(
        lambda runner: runner.config.multi_agent(policies_to_train=module_ids), local_env_runner=True
    )


def add_snapshot(algo: Algorithm, run: RunConfig, snapshot: Player, source_module: str) -> None:
    """Add a frozen copy of ``source_module`` as ``snapshot.name`` to learners and EnvRunners."""
    algo.add_module(module_id=snapshot.name, module_spec=learner_spec(run, snapshot.side, snapshot.reward_method))
    weights = algo.learner_group.get_weights(module_ids=[source_module])[source_module]
    algo.learner_group.set_weights({snapshot.name: weights})
    # Set directly: a weight sync would be skipped, the EnvRunners already hold the
    # learner group's current weights sequence number.
    algo.env_runner_group.foreach_env_runner(
        lambda runner: runner.module[snapshot.name].set_state(weights), local_env_runner=True
    )


def save_module(algo: Algorithm, module_id: str, path: Path) -> None:
    """Write one module (class, spaces, config and weights) for use without the algorithm."""
    module = algo.get_module(module_id)
    module.save_to_path(str(path))


def learner_weights(algo: Algorithm, module_id: str) -> dict[str, torch.Tensor]:
    return algo.learner_group.get_weights(module_ids=[module_id])[module_id]


# ---------------------------------------------------------------- checkpoints and results
def load_module(path: str | Path) -> torch.nn.Module:
    """A module saved by ``save_module``, in eval mode."""
    from ray.rllib.core.rl_module.rl_module import RLModule

    if not Path(path, "module_state.pkl").exists():
        raise FileNotFoundError(f"no saved module at {path} (module_state.pkl missing)")
    module = RLModule.from_checkpoint(str(Path(path).resolve()))
    module.eval()
    return module


def restore_algorithm(path: str | Path) -> Algorithm:
    """The algorithm of a checkpoint, snapshot modules added at run time included."""
    return Algorithm.from_checkpoint(str(path))


def learner_stats(result: dict[str, Any], modules: list[str]) -> dict[str, dict[str, Any]]:
    """The Learner's results (losses, entropy, KL, ...) of each of ``modules`` it trained in this ``train()``."""
    learners = result.get(LEARNER_RESULTS, {})
    return {m: dict(learners[m]) for m in modules if m in learners}


def load_frozen_module(algo: Algorithm, module_id: str, path: Path) -> None:
    """Set the weights of ``module_id`` (already in the algorithm) to the module saved at ``path``
    (``save_module``), in the learners and every EnvRunner: a frozen player of another run."""
    weights = load_module(path).get_state()
    algo.learner_group.set_weights({module_id: weights})
    algo.env_runner_group.foreach_env_runner(  # set directly, as in ``add_snapshot``
        lambda runner: runner.module[module_id].set_state(weights), local_env_runner=True
    )
