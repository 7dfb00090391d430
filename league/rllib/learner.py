"""``LeaguePPOLearner``: RLlib's PPO torch learner, updating from a ready batch in plain torch."""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass
from typing import Any

import torch

from league.rllib import compat
from league.rllib.flat_adam import FlatAdam
from league.rllib.modules import ActorCriticModule
from league.rllib.algorithm import COMPILED_LOSS, RESIDUAL_PENALTIES, RESIDUAL_PENALTY_GATED, SAMPLE_AHEAD
from league.rllib.ppo_loss import LossRows, PPOCoefficients, anchor_at_learner, loss_stats, ppo_loss
from league.rollout.train_batch import minibatch_rows
from ray.rllib.algorithms.ppo.torch.ppo_torch_learner import PPOTorchLearner
from ray.rllib.core.columns import Columns
from ray.rllib.policy.sample_batch import MultiAgentBatch


@dataclass
class ClippedStep:
    """One optimizer of a module in ``LeaguePPOLearner``'s update: its gradients clipped by
    global norm (``grad_clip``: the module's config), then stepped (as one buffer by ``flat``)."""

    module_id: str
    grad_clip: float | None
    name: str
    optimizer: Any
    flat: FlatAdam | None


@functools.cache
def compiled_ppo_loss() -> Any:
    """``ppo_loss`` under ``torch.compile`` (``ppo.compile_loss``), made once per process. Dynamo keeps a
    graph per module structure and minibatch shape (the three attackers of a league share one); the
    weights and RLlib's KL and entropy coefficients (tensors) are its inputs, so their changes compile
    nothing. Static shapes: a shape's kernels do not depend on which shapes came first, so a resumed
    run computes as the run never stopped."""
    return torch.compile(ppo_loss, dynamic=False)


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
    coefficients). ``tests/rllib/test_fast_path.py`` checks the weights equal to the bit and the
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
    (``build_config`` sets no RLlib ``torch.compile``, grad scaler or torch lr scheduler, which
    this update does not know; ``ppo.compile_loss`` compiles this update's loss, ``compiled_ppo_loss``.)

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
        bf16 = {m: self.module[m].settings.bf16 and compat.native_bf16() for m in modules}  # `PPOSettings.bf16`
        loss_of = compiled_ppo_loss() if self.config.learner_config_dict.get(COMPILED_LOSS) else ppo_loss
        if self.config.learner_config_dict.get(SAMPLE_AHEAD):  # sampled by the policy one update older
            for m in modules:
                anchor_at_learner(inputs[m], self.module[m], bf16[m])
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
                    loss_per_module[m], terms = loss_of(self.module[m], inputs[m].take(rows[m]), coefficients[m], bf16[m])
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
            residual_penalty=self.config.learner_config_dict.get(RESIDUAL_PENALTIES, {}).get(module_id, 0.0),
            residual_penalty_gated=self.config.learner_config_dict.get(RESIDUAL_PENALTY_GATED, False),
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
