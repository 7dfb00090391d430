"""RLlib ``MultiAgentEnv`` of one game: only an env, no training logic.

Register it with ``tune.register_env`` or pass the class as ``config.environment(env=...)``;
``env_config`` holds ``GameConfig`` fields. The one extra key, ``with_global_state``,
appends the 22-number global state (``envs.observations``) to every observation so that
a centralized critic can read it from the same batch; the actor part stays first.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from ray.rllib.env.multi_agent_env import MultiAgentEnv

from envs.agents import AGENTS
from envs.config import GameConfig
from envs.observations import GLOBAL_STATE_SIZE
from envs.single import SingleGame


class TargetDefenseMultiAgentEnv(MultiAgentEnv):
    """Same game as ``envs.pettingzoo_env.TargetDefenseEnv`` (see its docstring), RLlib API."""

    def __init__(self, env_config: dict[str, Any] | None = None):
        super().__init__()
        env_config = dict(env_config or {})
        self.with_global_state = bool(env_config.pop("with_global_state", False))
        self.config = GameConfig(**env_config)
        self.game = SingleGame(self.config)
        self.possible_agents = list(AGENTS)
        self.agents = list(AGENTS)
        self.action_spaces = dict(self.game.action_spaces)
        self.observation_spaces = {
            agent: self._extended(space) if self.with_global_state else space
            for agent, space in self.game.observation_spaces.items()
        }

    @staticmethod
    def _extended(space: spaces.Box) -> spaces.Box:
        return spaces.Box(-np.inf, np.inf, shape=(space.shape[0] + GLOBAL_STATE_SIZE,), dtype=np.float32)

    def _observe(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        if not self.with_global_state:
            return obs
        state = self.game.state()
        return {agent: np.concatenate((o, state)) for agent, o in obs.items()}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        self.agents = list(AGENTS)
        obs, infos = self.game.reset(seed, (options or {}).get("positions"))
        return self._observe(obs), infos

    def step(self, action_dict: dict[str, np.ndarray]):
        obs, rewards, done, infos = self.game.step(action_dict)
        terminateds = {agent: done for agent in AGENTS}
        terminateds["__all__"] = done
        truncateds = {agent: False for agent in AGENTS}
        truncateds["__all__"] = False
        if done:
            self.agents = []
        return self._observe(obs), rewards, terminateds, truncateds, infos
