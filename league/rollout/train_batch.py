"""PPO training data straight from rollout arrays, without episode objects (no Ray, no RLlib).

A rollout of ``G`` games over ``T`` steps is held as arrays ``[t, game]`` (the fast
sampler, ``league.rllib.env_runner``, fills them). ``slot_batch`` gives one module's rows as
one agent (a slot): where it played, and its advantages and value targets by ``gae`` over
the rewards it is paid (``league.rollout.training_reward``). For one module and one agent slot:

| array      | shape     | meaning                                                        |
| ---------- | --------- | -------------------------------------------------------------- |
| rewards    | (T, G)    | reward of step ``t``                                           |
| values     | (T, G)    | the critic's value of the observation before step ``t``        |
| bootstrap  | (G,)      | the critic's value of the observation after the last step      |
| ended      | (T, G)    | the game ended on step ``t`` (a termination: A captured T, ...) |

A game that ended on step ``t`` starts a new one on step ``t + 1``, so the recursion is
cut there; a game still running after the last row is a truncated chunk, bootstrapped
with ``bootstrap`` (its next call continues it). The time limit is a termination of the
game, not a truncation (``envs``), so nothing is bootstrapped after it.

This is the computation of RLlib's ``GeneralAdvantageEstimation`` learner connector on
the same steps, with one difference: advantages are standardised over the real steps
only (RLlib also counts the extra bootstrap step it appends to every chunk, whose
advantage is 0), as CleanRL's PPO does. ``tests/rllib/test_fast_path.py`` checks the two.

``minibatch_rows`` is the order in which RLlib's Learner passes over such a batch, for a
Learner that slices the arrays itself (``league.rllib.learner.LeaguePPOLearner``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from envs.agents import AGENTS
from envs.config import GameConfig
from league.rollout.games import Rows
from league.rollout.training_reward import TrainingPay, ended_steps, learner_rewards


def gae(
    rewards: np.ndarray, values: np.ndarray, bootstrap: np.ndarray, ended: np.ndarray, gamma: float, lambda_: float
) -> tuple[np.ndarray, np.ndarray]:
    """Generalised advantage estimates and value targets ``(T, G)`` (Schulman et al. 2016)."""
    advantages = np.zeros(values.shape, dtype=np.float64)
    next_value = np.asarray(bootstrap, dtype=np.float64)
    next_advantage = np.zeros_like(next_value)
    for t in range(len(rewards) - 1, -1, -1):
        live = 1.0 - ended[t]
        delta = rewards[t] + gamma * live * next_value - values[t]
        next_advantage = delta + gamma * lambda_ * live * next_advantage
        advantages[t] = next_advantage
        next_value = values[t]
    return advantages, advantages + values


@dataclass(frozen=True)
class SlotBatch:
    """One module's rows as one agent: the steps ``(t, game)`` it played (``played``, ``(T, G)``),
    and at those steps, in row-major order, its advantages (not yet standardised) and value targets."""

    played: np.ndarray
    advantages: np.ndarray
    value_targets: np.ndarray


def slot_batch(
    rows: Rows, t: int, module: int, agent: str, pay: TrainingPay, values_of: Callable[[np.ndarray], np.ndarray],
    game: GameConfig,
) -> SlotBatch | None:
    """The PPO targets of module index ``module`` as ``agent`` over rows ``0..t - 1`` (``None``:
    it did not play ``agent``), paid as ``pay``; ``values_of(observations)`` is its critic."""
    played = rows.modules[:t, :, AGENTS.index(agent)] == module  # (t, G)
    if not played.any():
        return None
    # The observation after the last row is bootstrapped by whoever played the last step.
    observed = np.concatenate((played, played[-1:]))
    values = np.zeros(observed.shape)
    values[observed] = values_of(rows.observations[agent][: t + 1][observed])
    rewards = learner_rewards(pay, agent, rows, t, game)
    advantages, targets = gae(rewards, values[:t], values[t], ended_steps(rows.outcome[:t]), pay.gamma, pay.lambda_)
    return SlotBatch(played, advantages[played].astype(np.float32), targets[played].astype(np.float32))


def standardized(advantages: np.ndarray) -> np.ndarray:
    """Zero mean, unit standard deviation (the floor 1e-4 as RLlib's connector has it)."""
    return (advantages - advantages.mean()) / max(1e-4, float(advantages.std()))


def minibatch_rows(
    lengths: dict[str, int], minibatch_size: int, num_epochs: int, shuffle: bool
) -> Iterator[dict[str, np.ndarray]]:
    """Row indices of each minibatch, per module, in the order RLlib's ``MiniBatchCyclicIterator``
    takes them (Ray 2.60), drawing the same shuffles from NumPy's global generator.

    Each module's rows are read in order, ``minibatch_size`` at a time; a minibatch that
    reaches the end of the rows takes the rest from the start again, and every time the end
    is reached (the last epoch's too) that module's rows are shuffled. Minibatches come until
    every module's rows were passed ``num_epochs`` times, so a module with fewer rows takes
    more passes.
    """
    if min(lengths.values(), default=1) < 1:
        raise ValueError(f"a module without rows cannot be passed over: {lengths}")
    order = {module_id: np.arange(n) for module_id, n in lengths.items()}
    start = dict.fromkeys(lengths, 0)
    passes = dict.fromkeys(lengths, 0)
    while lengths and min(passes.values()) < num_epochs:
        minibatch = {}
        for module_id, n in lengths.items():
            s, needed, pieces = start[module_id], minibatch_size, []
            while s + needed >= n:
                pieces.append(order[module_id][s:])
                needed -= n - s
                s = 0
                passes[module_id] += 1
                if shuffle:
                    order[module_id] = order[module_id][np.random.permutation(n)]
            if needed > 0:
                pieces.append(order[module_id][s : s + needed])
            start[module_id] = s + needed
            minibatch[module_id] = np.concatenate(pieces)
        yield minibatch
