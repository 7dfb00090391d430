"""RLlib's PPO loss for ``league.rllib.modules.ActorCriticModule``, in plain torch.

The formula and the order of operations of Ray 2.60's ``PPOTorchLearner.compute_loss_for_module``
(no loss mask, with a critic), the diagonal Gaussian's log-probability, entropy and KL as
RLlib's ``TorchDiagGaussian`` gets them from ``torch.distributions.Normal``, written out:

    ratio   = exp(logp(actions) - logp_old)
    loss    = mean(-min(A ratio, A clip(ratio, 1 - clip_param, 1 + clip_param))
                   + vf_loss_coeff clamp((V - V_target)^2, 0, vf_clip_param)
                   - entropy_coeff entropy)
              + kl_coeff mean(KL(old || new))        (if ``use_kl_loss``)

The same operations in the same order give the same gradients to the bit: autograd adds
the gradients that reach one tensor in the order the graph was built, so the terms are
built in RLlib's order (``tests/rllib/test_fast_path.py`` checks the weights after an update
equal to RLlib's). What is left out: RLlib's distribution objects and forward wrappers,
and the statistics, which ``loss_stats`` computes only for the minibatch whose statistics
are reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
import torch

from ray.rllib.algorithms.ppo.ppo import (
    LEARNER_RESULTS_KL_KEY,
    LEARNER_RESULTS_VF_EXPLAINED_VAR_KEY,
    LEARNER_RESULTS_VF_LOSS_UNCLIPPED_KEY,
)
from ray.rllib.core.columns import Columns
from ray.rllib.core.learner.learner import ENTROPY_KEY, POLICY_LOSS_KEY, VF_LOSS_KEY
from ray.rllib.evaluation.postprocessing import Postprocessing
from ray.rllib.utils.torch_utils import explained_variance

# The batch columns the loss reads.
LOSS_COLUMNS = (
    Columns.OBS,
    Columns.ACTIONS,
    Columns.ACTION_LOGP,
    Columns.ACTION_DIST_INPUTS,
    Postprocessing.ADVANTAGES,
    Postprocessing.VALUE_TARGETS,
)
VECTOR_COLUMNS = {Columns.OBS, Columns.ACTIONS, Columns.ACTION_DIST_INPUTS}  # one row per step, several numbers
LOG_SQRT_2PI = math.log(math.sqrt(2 * math.pi))  # as `Normal.log_prob` writes it
ENTROPY_CONSTANT = 0.5 + 0.5 * math.log(2 * math.pi)  # as `Normal.entropy` writes it (Python floats)


class LossRows:
    """The loss's columns of one module's batch side by side in one float32 matrix, so that a
    minibatch's rows are one ``index_select`` (RLlib's tensors are float32 too).

    A minibatch's columns are strided views where RLlib's are tensors of their own; the loss
    adds, multiplies and compares them, reads them through a matrix product, or (the old
    log standard deviation's ``exp``) in rows of a few numbers as RLlib does: the same numbers.
    """

    def __init__(self, columns: Mapping[str, Any], device: Any = None) -> None:
        self.length = len(columns[LOSS_COLUMNS[0]])
        arrays = [np.asarray(columns[key], dtype=np.float32).reshape(self.length, -1) for key in LOSS_COLUMNS]
        self.columns: dict[str, slice | int] = {}
        start = 0
        for key, array in zip(LOSS_COLUMNS, arrays):
            width = array.shape[1]
            self.columns[key] = slice(start, start + width) if key in VECTOR_COLUMNS else start
            start += width
        self.matrix = torch.from_numpy(np.concatenate(arrays, axis=1)).to(device)

    def take(self, rows: np.ndarray) -> dict[str, torch.Tensor]:
        """The columns of ``rows``, in that order (views into one gathered matrix)."""
        picked = self.matrix.index_select(0, torch.from_numpy(rows).to(self.matrix.device))
        return {key: picked[:, where] for key, where in self.columns.items()}


def anchor_at_learner(rows: LossRows, module: Any, bf16: bool = False) -> None:
    """Decoupled PPO (Hilton et al. 2021, "Batch size-invariance for policy optimization") for rows sampled by
    an older policy than the learner's (``resources.sample_ahead``: one update older). PPO's clip keeps the new
    policy near the one that sampled, which the learner has already left by an update: its room to move
    shrinks, and on the flagship's attacker phase entropy fell half as fast. So the clip and the KL term are
    anchored at the learner's policy as the update starts (``ACTION_LOGP``, ``ACTION_DIST_INPUTS`` replaced by
    its), and each row's advantage weighted by that policy's probability over the sampling policy's, the
    importance weight that keeps the objective's expectation the learner's (not clipped: a lag of one update
    keeps it near 1)."""
    columns = rows.columns
    with torch.no_grad(), torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
        dist_inputs = module.action_dist_inputs(rows.matrix[:, columns[Columns.OBS]]).float()
    loc, log_std = dist_inputs.chunk(2, dim=-1)
    scale = log_std.exp()
    actions = rows.matrix[:, columns[Columns.ACTIONS]]
    logp = (-((actions - loc) ** 2) / (2 * scale**2) - scale.log() - LOG_SQRT_2PI).sum(-1)
    weight = torch.exp(logp - rows.matrix[:, columns[Columns.ACTION_LOGP]])
    rows.matrix[:, columns[Postprocessing.ADVANTAGES]] *= weight
    rows.matrix[:, columns[Columns.ACTION_LOGP]] = logp
    rows.matrix[:, columns[Columns.ACTION_DIST_INPUTS]] = dist_inputs


@dataclass(frozen=True)
class PPOCoefficients:
    """One module's loss settings for one update (``entropy_coeff`` and ``kl_coeff`` are
    RLlib's current values, the tensors its loss multiplies by; ``kl_coeff`` None: no KL term;
    ``residual_penalty``, ``residual_penalty_gated``: ``PPOSettings.attacker_residual_penalty`` and its
    gate, not RLlib's)."""

    clip_param: float
    vf_clip_param: float
    vf_loss_coeff: float
    entropy_coeff: Any
    kl_coeff: Any
    residual_penalty: float = 0.0
    residual_penalty_gated: bool = False


@dataclass
class LossTerms:
    """The per-row terms of one minibatch's loss, for its statistics."""

    surrogate: torch.Tensor
    vf_loss: torch.Tensor
    vf_loss_clipped: torch.Tensor
    entropy: torch.Tensor
    mean_kl: torch.Tensor | None
    values: torch.Tensor
    value_targets: torch.Tensor


def ppo_loss(
    module: Any, batch: Mapping[str, torch.Tensor], c: PPOCoefficients, bf16: bool = False
) -> tuple[torch.Tensor, LossTerms]:
    """The total loss of ``module`` on the minibatch ``batch`` and its terms; with ``bf16`` the
    networks run under bfloat16 autocast and their outputs come back float32, so that the
    ratios, logs and means of the loss keep float32's precision."""
    with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
        # RLlib: forward_train, then TorchDiagGaussian.from_logits: chunk, exp.
        if c.residual_penalty:  # the network's correction of the prior too, from the same pass
            dist_inputs, correction = module.prior_correction(batch[Columns.OBS])
            dist_inputs, correction = dist_inputs.float(), correction.float()
        else:
            dist_inputs = module.action_dist_inputs(batch[Columns.OBS]).float()
    loc, log_std = dist_inputs.chunk(2, dim=-1)
    scale = log_std.exp()
    # Normal.log_prob(actions), summed over the action's dimensions.
    var = scale**2
    log_scale = scale.log()
    logp = (-((batch[Columns.ACTIONS] - loc) ** 2) / (2 * var) - log_scale - LOG_SQRT_2PI).sum(-1)
    logp_ratio = torch.exp(logp - batch[Columns.ACTION_LOGP])
    mean_kl = None
    if c.kl_coeff is not None:  # torch's KL(Normal p || Normal q) with p the sampling policy's
        old_loc, old_log_std = batch[Columns.ACTION_DIST_INPUTS].chunk(2, dim=-1)
        old_scale = old_log_std.exp()
        var_ratio = (old_scale / scale).pow(2)
        t1 = ((old_loc - loc) / scale).pow(2)
        mean_kl = torch.mean((0.5 * (var_ratio + t1 - 1 - var_ratio.log())).sum(-1))
    entropy = (ENTROPY_CONSTANT + torch.log(scale)).sum(-1)
    advantages = batch[Postprocessing.ADVANTAGES]
    surrogate = torch.min(
        advantages * logp_ratio, advantages * torch.clamp(logp_ratio, 1 - c.clip_param, 1 + c.clip_param)
    )
    with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
        values = module.compute_values({Columns.OBS: batch[Columns.OBS]}).float()
    value_targets = batch[Postprocessing.VALUE_TARGETS]
    vf_loss = torch.pow(values - value_targets, 2.0)
    vf_loss_clipped = torch.clamp(vf_loss, 0, c.vf_clip_param)
    total = torch.mean(-surrogate + c.vf_loss_coeff * vf_loss_clipped - (c.entropy_coeff * entropy))
    if mean_kl is not None:
        total += c.kl_coeff * mean_kl
    if c.residual_penalty:  # after RLlib's terms: without it the update stays RLlib's to the bit
        square = correction.pow(2).sum(-1)
        if c.residual_penalty_gated:
            square = square * module.targeter_still_straight(batch[Columns.OBS])
        total += c.residual_penalty * square.mean()
    return total, LossTerms(surrogate, vf_loss, vf_loss_clipped, entropy, mean_kl, values, value_targets)


def loss_stats(terms: LossTerms) -> dict[str, torch.Tensor]:
    """The statistics RLlib logs of a minibatch's loss, under its keys."""
    return {
        POLICY_LOSS_KEY: -torch.mean(terms.surrogate),
        VF_LOSS_KEY: torch.mean(terms.vf_loss_clipped),
        LEARNER_RESULTS_VF_LOSS_UNCLIPPED_KEY: torch.mean(terms.vf_loss),
        LEARNER_RESULTS_VF_EXPLAINED_VAR_KEY: explained_variance(terms.value_targets.contiguous(), terms.values),
        ENTROPY_KEY: torch.mean(terms.entropy),
        LEARNER_RESULTS_KL_KEY: terms.mean_kl if terms.mean_kl is not None else torch.tensor(0.0),
    }
