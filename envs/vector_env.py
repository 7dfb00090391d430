"""N games of the RLlib env as arrays, for samplers that step every game at once.

Game for game, this gives what a vector of ``envs.rllib_env.TargetDefenseMultiAgentEnv``
would: the same observations (with the global state appended if ``with_global_state``),
rewards and info dicts, and the same starts: game ``i`` draws from its own generator,
seeded ``seed + i`` as a vector env reset with ``seed`` seeds its sub-envs, and a reset
without a seed continues it.

No auto-reset: ``step`` returns the final observations of the games that ended, and the
caller starts them anew with ``reset_games`` once it has stored them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from envs.agents import AGENTS
from envs.config import GameConfig
from envs.core import BatchedGame
from envs.observations import global_state, observe, policy_input
from envs.scenarios import UNIFORMS_PER_START, positions_from_uniform
from envs.single import step_infos


@dataclass
class VectorStep:
    """One step of every game."""

    observations: dict[str, np.ndarray]  # agent -> (N, size) float32, final ones for games that ended (agents asked)
    rewards: dict[str, np.ndarray]  # agent -> (N,) float
    done: np.ndarray  # (N,) bool: the game ended on this step
    outcome: np.ndarray  # (N,) int ``Outcome`` value, RUNNING while going on
    steps: np.ndarray  # (N,) int: steps played in the game so far
    time_limit: np.ndarray  # (N,) int
    attacker_rewards: np.ndarray  # (N, 3) float: A's reward under methods 1, 2, 3

    def infos(self, game: int) -> dict[str, dict[str, Any]]:
        """Game ``game``'s info dicts, as the single-game env returns them."""
        return step_infos(
            int(self.steps[game]), int(self.time_limit[game]), int(self.outcome[game]), self.attacker_rewards[game]
        )


class TargetDefenseVectorEnv:
    """``num_games`` games; ``env_config`` as for ``TargetDefenseMultiAgentEnv``."""

    def __init__(self, env_config: dict[str, Any], num_games: int):
        env_config = dict(env_config)
        self.with_global_state = bool(env_config.pop("with_global_state", False))
        self.config = GameConfig(**env_config)
        self.num_games = num_games
        self.core = BatchedGame(self.config, num_games)
        self.generators = [np.random.default_rng() for _ in range(num_games)]

    def reset(self, seed: int | None = None, positions: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Start every game; with ``seed``, game ``i``'s generator is seeded ``seed + i``; with
        ``positions`` ``(N, 3, 3)``, game ``i`` starts from ``positions[i]`` (the fixed
        evaluation games) and the generators are not drawn from."""
        if seed is not None:
            self.generators = [np.random.default_rng(seed + i) for i in range(self.num_games)]
        if positions is None:
            return self.reset_games(np.arange(self.num_games))
        self.core.reset(positions=positions)
        return self.observations()

    def reset_games(self, games: np.ndarray, agents: tuple[str, ...] = AGENTS) -> dict[str, np.ndarray]:
        """Start the games at indices ``games`` anew, each from its own generator; their observations
        (of ``agents`` only: a sampler whose scripted players act on ``core`` needs no others)."""
        games = np.asarray(games, dtype=np.int64)
        if len(games):
            # `sample_positions` with n = 1 for each game, drawn from each game's generator.
            uniform = np.stack([self.generators[g].random(UNIFORMS_PER_START) for g in games])
            starts = positions_from_uniform(self.config.scenario, uniform)
            self.core.reset_games(games, positions=starts)
        return self.observations(games, agents)

    def observations(self, games: np.ndarray | None = None, agents: tuple[str, ...] = AGENTS) -> dict[str, np.ndarray]:
        """Every game's observations, or those of ``games`` only (rows in that order), of ``agents``."""
        if not agents:
            return {}
        core, rows = self.core, slice(None) if games is None else games
        positions, headings, time_left = core.positions[rows], core.headings[rows], core.time_left[rows]
        observations = observe(
            self.config, positions, headings, time_left, [AGENTS.index(a) for a in agents],
            targeter_turned_away=core.targeter_turned_away[rows],
        )
        if self.with_global_state:
            state = global_state(self.config, positions, headings, time_left)
            observations = [policy_input(obs, state) for obs in observations]
        return dict(zip(agents, observations))

    def step(self, actions: dict[str, np.ndarray], agents: tuple[str, ...] = AGENTS) -> VectorStep:
        """Step every running game with ``actions`` (agent -> ``(N, 2)``); observations of ``agents``."""
        result = self.core.step(np.stack([np.asarray(actions[agent]) for agent in AGENTS], axis=1))
        return VectorStep(
            observations=self.observations(agents=agents),
            rewards={agent: result.rewards[:, i] for i, agent in enumerate(AGENTS)},
            done=result.done,
            outcome=result.outcome,
            steps=self.core.steps.copy(),
            time_limit=self.core.time_limit.copy(),
            attacker_rewards=result.attacker_rewards,
        )
