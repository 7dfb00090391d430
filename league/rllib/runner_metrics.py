"""What the league's env runner logs to RLlib's metrics: the standard runner's per-episode
metrics and sampled-step counts, and the league's outcome counts (``bridge.episode_outcomes``
reads them back from a ``train()`` result).

Of the per-episode metrics (windows of the last 100 episodes) only the episodes that can
still be in a window are logged, once at the end of each play (``FinishedGames.log``).
"""

from __future__ import annotations

import math
import time
from collections import Counter, defaultdict
from typing import Any

import numpy as np

from envs.agents import AGENTS, Outcome
from league.rollout.games import Rollout
from ray.rllib.utils.metrics import (
    EPISODE_AGENT_RETURN_MEAN,
    EPISODE_AGENT_STEPS,
    EPISODE_DURATION_SEC_MEAN,
    EPISODE_LEN_MAX,
    EPISODE_LEN_MEAN,
    EPISODE_LEN_MIN,
    EPISODE_MODULE_RETURN_MEAN,
    EPISODE_RETURN_MAX,
    EPISODE_RETURN_MEAN,
    EPISODE_RETURN_MIN,
    NUM_AGENT_STEPS_SAMPLED,
    NUM_AGENT_STEPS_SAMPLED_LIFETIME,
    NUM_ENV_STEPS_SAMPLED,
    NUM_ENV_STEPS_SAMPLED_LIFETIME,
    NUM_EPISODES,
    NUM_EPISODES_LIFETIME,
    NUM_MODULE_STEPS_SAMPLED,
    NUM_MODULE_STEPS_SAMPLED_LIFETIME,
)

OUTCOMES_KEY = "league_outcomes"  # metrics key of the finished games by modules and outcome
SEPARATOR = "|"


def log_outcome(metrics: Any, modules: list[str], outcome: str, count: int = 1) -> None:
    """Count ``count`` finished games by their (attacker, targeter, defender) modules and outcome."""
    metrics.log_value((OUTCOMES_KEY, SEPARATOR.join(modules), outcome), count, reduce="sum")


class FinishedGames:
    """The games that ended in one play, kept to be logged at its end: one metrics call per
    key, not one per game."""

    def __init__(self) -> None:
        self.episodes: list[tuple[int, dict[str, float], dict[str, float], float]] = []
        """(length, agent returns, module returns, seconds) per finished episode."""
        self.outcomes: Counter[tuple[tuple[str, ...], str]] = Counter()
        """Finished games by (modules, outcome label) that no episode callback counts (the fast path)."""

    def add(self, rollout: Rollout, game: int, length: int, outcome: int | None = None) -> None:
        """``game`` of ``rollout`` ended after ``length`` steps; ``outcome``: count it here too."""
        returns = dict(zip(AGENTS, rollout.returns[game].tolist()))
        modules = [rollout.module_ids[index] for index in rollout.modules[game]]
        module_returns: dict[str, float] = defaultdict(float)
        for agent, module_id in zip(AGENTS, modules):
            module_returns[module_id] += returns[agent]
        self.episodes.append((length, returns, dict(module_returns), time.perf_counter() - rollout.started[game]))
        if outcome is not None:
            self.outcomes[(tuple(modules), Outcome(outcome).label)] += 1

    def log(self, metrics: Any, num_episodes_for_smoothing: int, num_env_runners: int) -> None:
        """The standard runner's episode metrics, for the episodes a window can still hold, and
        the outcomes counted; then forget them."""
        window = max(1, math.ceil(num_episodes_for_smoothing / (num_env_runners or 1)))
        for length, returns, module_returns, duration in self.episodes[-window:]:
            total = sum(returns.values())
            means = {
                EPISODE_LEN_MEAN: length,
                EPISODE_RETURN_MEAN: total,
                EPISODE_DURATION_SEC_MEAN: duration,
                **{(EPISODE_AGENT_RETURN_MEAN, agent): value for agent, value in returns.items()},
                **{(EPISODE_AGENT_STEPS, agent): length for agent in AGENTS},
                **{(EPISODE_MODULE_RETURN_MEAN, module): value for module, value in module_returns.items()},
            }
            for key, value in means.items():  # leaf by leaf: `log_dict` maps `tree` over the dict each call
                metrics.log_value(key, value, window=window)
            for reduce, (length_key, return_key) in (
                ("min", (EPISODE_LEN_MIN, EPISODE_RETURN_MIN)),
                ("max", (EPISODE_LEN_MAX, EPISODE_RETURN_MAX)),
            ):
                metrics.log_value(length_key, length, reduce=reduce, window=window)
                metrics.log_value(return_key, total, reduce=reduce, window=window)
        self.episodes.clear()
        for (modules, outcome), count in self.outcomes.items():
            log_outcome(metrics, list(modules), outcome, count)
        self.outcomes.clear()


def log_sampled_steps(metrics: Any, env_steps: int, episodes: int, module_steps: dict[str, int]) -> None:
    """The standard runner's counts of one play: env, agent and module steps, episodes ended."""
    metrics.log_value(NUM_ENV_STEPS_SAMPLED, env_steps, reduce="sum")
    metrics.log_value(NUM_ENV_STEPS_SAMPLED_LIFETIME, env_steps, reduce="lifetime_sum", with_throughput=True)
    metrics.log_value(NUM_EPISODES, episodes, reduce="sum")
    metrics.log_value(NUM_EPISODES_LIFETIME, episodes, reduce="lifetime_sum")
    for agent in AGENTS:
        metrics.log_value((NUM_AGENT_STEPS_SAMPLED, agent), env_steps, reduce="sum")
        metrics.log_value((NUM_AGENT_STEPS_SAMPLED_LIFETIME, agent), env_steps, reduce="lifetime_sum")
    for module_id, steps in module_steps.items():
        metrics.log_value((NUM_MODULE_STEPS_SAMPLED, module_id), steps, reduce="sum")
        metrics.log_value((NUM_MODULE_STEPS_SAMPLED_LIFETIME, module_id), steps, reduce="lifetime_sum")


def module_step_counts(rollout: Rollout, module_steps: np.ndarray) -> dict[str, int]:
    """Module id -> steps played, of the modules that played (``module_steps`` by index of ``rollout.module_ids``)."""
    return {rollout.module_ids[index]: steps for index, steps in enumerate(module_steps.tolist()) if steps}
