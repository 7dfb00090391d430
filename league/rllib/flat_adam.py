"""Adam's step of a module's many small tensors as one tensor: the same numbers, fewer operations.

torch's Adam on CPU steps a list of tensors one tensor at a time (its foreach operations
loop over the list in C++), about ten operations per tensor; an ``ActorCriticModule`` of
[64, 64] networks has 13 tensors of at most 4,096 numbers, so its step is mostly dispatch.
``FlatAdam`` makes the parameters and Adam's two moments views of one buffer each, for one
update, and steps the buffer with torch's own Adam function (``torch.optim.adam.adam``,
what ``Adam.step`` calls, with the arguments ``Adam.step`` passes).

Adam's arithmetic is elementwise, so every number is computed by the same operations as
before. One caveat: torch's vectorised loops take a tensor's numbers in vector registers and
the remainder (its size modulo the loop's stride) one at a time, and the two paths may round
differently (fused multiply-add). Only tensors whose size is a multiple of ``CHUNK`` go into
the buffer, so none of their numbers is a remainder in either layout; the others (the
3-number log standard deviation, the last layers' biases) stay tensors of their own.
``tests/rllib/test_fast_path.py`` checks the weights after an update equal to the bit with RLlib's.
"""

from __future__ import annotations

from typing import Any

import torch
from torch.optim.adam import adam

# Numbers per vectorised loop step are 2 registers: 16 float32 with AVX2, 32 with AVX-512.
CHUNK = 64


class FlatAdam:
    """One ``torch.optim.Adam`` (foreach, one parameter group, moments already initialised)
    stepped as one buffer until ``release``. Use: ``gather_gradients``, clip the gradients
    of ``parameters``, ``step``."""

    @staticmethod
    def applies(optimizer: Any) -> bool:
        """Whether the optimizer steps as ``Adam.step`` does with these arguments (plain
        foreach Adam on float32 tensors that each have one step count, all the same), and
        has tensors to flatten."""
        if type(optimizer) is not torch.optim.Adam or len(optimizer.param_groups) != 1:
            return False
        group = optimizer.param_groups[0]
        plain = group["foreach"] and not any(group[k] for k in ("amsgrad", "fused", "capturable", "differentiable"))
        states = [optimizer.state.get(p, {}) for p in group["params"]]
        steps = {float(s["step"]) for s in states if "step" in s}
        initialised = all("exp_avg" in s for s in states) and len(steps) == 1
        flat = any(p.numel() % CHUNK == 0 for p in group["params"])
        return plain and initialised and flat and all(p.dtype == torch.float32 for p in group["params"])

    def __init__(self, optimizer: torch.optim.Adam) -> None:
        self.optimizer = optimizer
        self.group = optimizer.param_groups[0]
        state = optimizer.state
        self.flat = [p for p in self.group["params"] if p.numel() % CHUNK == 0]
        self.separate = [p for p in self.group["params"] if p.numel() % CHUNK != 0]
        sizes = [p.numel() for p in self.flat]
        buffers = {}
        for key in ("param", "exp_avg", "exp_avg_sq"):
            tensors = [p.detach() if key == "param" else state[p][key] for p in self.flat]
            buffers[key] = torch.cat([t.reshape(-1) for t in tensors])
            for p, view in zip(self.flat, buffers[key].split(sizes)):
                if key == "param":
                    p.data = view.view_as(p)  # the module computes with the buffer's numbers
                else:
                    state[p][key] = view.view_as(p)  # (RLlib's fallback step updates the views in place)
        self.buffer, self.exp_avg, self.exp_avg_sq = buffers["param"], buffers["exp_avg"], buffers["exp_avg_sq"]
        self.step_count = state[self.flat[0]]["step"].clone()
        self.parameters = [self.buffer] + self.separate

    def gather_gradients(self) -> None:
        """The buffer's gradient: the flat parameters' gradients, in their order."""
        self.buffer.grad = torch.cat([p.grad.reshape(-1) for p in self.flat])

    @torch.no_grad()
    def step(self) -> None:
        state, group = self.optimizer.state, self.group
        beta1, beta2 = group["betas"]
        adam(
            self.parameters,
            [p.grad for p in self.parameters],
            [self.exp_avg] + [state[p]["exp_avg"] for p in self.separate],
            [self.exp_avg_sq] + [state[p]["exp_avg_sq"] for p in self.separate],
            [],
            [self.step_count] + [state[p]["step"] for p in self.separate],
            amsgrad=False,
            has_complex=False,
            beta1=beta1,
            beta2=beta2,
            lr=group["lr"],
            weight_decay=group["weight_decay"],
            eps=group["eps"],
            maximize=group["maximize"],
            foreach=True,
            capturable=False,
            differentiable=False,
            fused=None,
            grad_scale=getattr(self.optimizer, "grad_scale", None),
            found_inf=getattr(self.optimizer, "found_inf", None),
            decoupled_weight_decay=group["decoupled_weight_decay"],
        )

    def release(self) -> None:
        """Give every parameter and moment its own storage again, the step counts the buffer's."""
        state = self.optimizer.state
        for p in self.flat:
            p.data = p.data.clone()
            for key in ("exp_avg", "exp_avg_sq"):
                state[p][key] = state[p][key].clone()
            state[p]["step"].copy_(self.step_count)
        self.buffer.grad = None
