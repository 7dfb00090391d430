"""One game seen agent by agent: the shared body of the PettingZoo and RLlib adapters.

It runs the batched core with ``N = 1``, so single-game and batched play follow the
same code, and it owns the seeding: ``reset(seed)`` makes a new generator, a reset
without a seed continues the last one.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np
from gymnasium import spaces

from envs.agents import AGENTS, Outcome
from envs.config import GameConfig
from envs.core import BatchedGame
from envs.observations import GLOBAL_STATE_SIZE, observation_size


def action_space(config: GameConfig) -> spaces.Box:
    if config.action_mode == "relative":
        return spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
    return spaces.Box(
        np.array([0.0, -math.pi / 2], dtype=np.float32),
        np.array([2 * math.pi, math.pi / 2], dtype=np.float32),
        dtype=np.float32,
    )


def observation_space(config: GameConfig, agent: str) -> spaces.Box:
    size = observation_size(config, AGENTS.index(agent))
    return spaces.Box(-np.inf, np.inf, shape=(size,), dtype=np.float32)


def state_space() -> spaces.Box:
    return spaces.Box(-np.inf, np.inf, shape=(GLOBAL_STATE_SIZE,), dtype=np.float32)


class SingleGame:
    """A batch of one game with dict-of-agents inputs and outputs."""

    def __init__(self, config: GameConfig):
        self.config = config
        self.core = BatchedGame(config, 1)
        self.rng = np.random.default_rng()
        self.observation_spaces = {agent: observation_space(config, agent) for agent in AGENTS}
        self.action_spaces = {agent: action_space(config) for agent in AGENTS}

    def reset(
        self, seed: int | None = None, positions: np.ndarray | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        """Start a game drawn from the seeded generator, or from ``positions`` ``(3, 3)``."""
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        if positions is None:
            self.core.reset(self.rng)
        else:
            self.core.reset(positions=np.asarray(positions, dtype=np.float64)[None])
        return self.observations(), {agent: {} for agent in AGENTS}

    def observations(self) -> dict[str, np.ndarray]:
        return {agent: obs[0] for agent, obs in zip(AGENTS, self.core.observations())}

    def state(self) -> np.ndarray:
        state: np.ndarray = self.core.global_state()[0]
        return state

    def step(
        self, actions: dict[str, Any]
    ) -> tuple[dict[str, np.ndarray], dict[str, float], bool, dict[str, dict[str, Any]]]:
        """Returns ``(observations, rewards, done, infos)``; ``done`` ends the game for all."""
        if not self.core.active[0]:
            raise RuntimeError("the game has ended: call reset() before step()")
        missing = [agent for agent in AGENTS if agent not in actions]
        unknown = [agent for agent in actions if agent not in AGENTS]
        if missing or unknown:
            raise ValueError(f"actions need exactly the agents {AGENTS}; missing {missing}, unknown {unknown}")
        batch = []
        for agent in AGENTS:
            action = np.asarray(actions[agent], dtype=np.float64)
            if action.shape != (2,):
                raise ValueError(f"action of {agent!r} must have shape (2,), got {action.shape}")
            if not np.all(np.isfinite(action)):
                raise ValueError(f"action of {agent!r} contains NaN or infinity: {action}")
            batch.append(action)
        result = self.core.step(np.stack(batch)[None])
        rewards = {agent: float(r) for agent, r in zip(AGENTS, result.rewards[0])}
        done = bool(result.done[0])
        core = self.core
        infos = step_infos(int(core.steps[0]), int(core.time_limit[0]), int(result.outcome[0]), result.attacker_rewards[0])
        return self.observations(), rewards, done, infos


def step_infos(step: int, time_limit: int, outcome: int, attacker_rewards: Sequence[float]) -> dict[str, dict[str, Any]]:
    """The per-agent info dicts of one step of one game (every adapter returns these)."""
    infos = infos_of_steps([step], [time_limit], [outcome], [attacker_rewards])
    return {agent: steps[0] for agent, steps in infos.items()}


def infos_of_steps(
    steps: Sequence[int],
    time_limits: Sequence[int],
    outcomes: Sequence[int],
    attacker_rewards: Sequence[Sequence[float]],
    agents: Sequence[str] = AGENTS,
) -> dict[str, list[dict[str, Any]]]:
    """Info dicts of ``agents`` over consecutive steps of one game, from per-step values."""
    common: list[dict[str, Any]] = [{"step": int(s), "time_limit": int(t)} for s, t in zip(steps, time_limits)]
    for info, outcome in zip(common, outcomes):
        if outcome != Outcome.RUNNING:
            ended = Outcome(int(outcome))
            info.update(outcome=ended.label, attacker_won=ended.attacker_wins)
    infos = {agent: [dict(info) for info in common] for agent in agents}
    # A's reward under each method (1, 2, 3), for leagues mixing attacker reward methods.
    for info, rewards in zip(infos.get("attacker", ()), attacker_rewards):
        info["attacker_rewards"] = list(map(float, rewards))
    return infos
