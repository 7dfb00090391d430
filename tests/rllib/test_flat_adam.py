"""``FlatAdam``: Adam's step of a module's tensors as one buffer gives Adam's numbers to the bit.

``tests/rllib/test_fast_path.py`` compares whole updates with RLlib's on small networks, where one
tensor is flattened; here the shipped networks, where most are.
"""

import copy

import numpy as np
import pytest
import torch

from league.config import load_config
from league.rllib.flat_adam import FlatAdam
from league.rllib.bridge import learner_spec


@pytest.mark.parametrize("side, reward_method", [("attacker", 2), ("team", None)])
def test_flat_steps_equal_adams_steps_on_the_shipped_networks(side, reward_method):
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    module = learner_spec(load_config("attacker_method2"), side, reward_method).build()
    adam = torch.optim.Adam(module.parameters(), lr=1e-3, foreach=True)
    params = list(module.parameters())

    def gradients():  # of magnitudes 1e-6 to 10, as after clipping or not
        return [torch.randn_like(p) * 10.0 ** float(rng.integers(-6, 2)) for p in params]

    for p, g in zip(params, gradients()):  # FlatAdam starts from initialised moments
        p.grad = g
    adam.step()
    twin, flat_adam = copy.deepcopy((module, adam))  # (an optimizer's state_dict shares the step tensors)
    twin_params = list(twin.parameters())
    assert FlatAdam.applies(flat_adam)
    flat = FlatAdam(flat_adam)
    assert len(flat.flat) >= len(params) - 3  # all but the log std and the output biases
    for _ in range(30):
        grads = gradients()
        for p, q, g in zip(params, twin_params, grads):
            p.grad, q.grad = g.clone(), g.clone()
        norm = torch.nn.utils.get_total_norm([p.grad for p in params], foreach=True)
        torch.nn.utils.clip_grads_with_norm_(params, 0.5, norm, foreach=True)
        adam.step()
        flat.gather_gradients()
        torch.nn.utils.clip_grads_with_norm_(flat.parameters, 0.5, norm, foreach=True)
        flat.step()
    flat.release()
    for p, q in zip(params, twin_params):
        assert torch.equal(p, q)
        assert q.untyped_storage().data_ptr() != flat.buffer.untyped_storage().data_ptr()  # released
        for key in ("exp_avg", "exp_avg_sq", "step"):
            assert torch.equal(adam.state[p][key], flat_adam.state[q][key]), key
