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
from envs.observations import policy_input, policy_input_size
from envs.single import SingleGame, observation_space


def policy_input_space(config: GameConfig, agent: str) -> spaces.Box:
    """The observation space of an env made ``with_global_state``: ``[own observation | global state]``."""
    return spaces.Box(-np.inf, np.inf, shape=(policy_input_size(config, AGENTS.index(agent)),), dtype=np.float32)


class TargetDefenseMultiAgentEnv(MultiAgentEnv):
    """Same game as ``envs.pettingzoo_env.TargetDefenseEnv`` (see its docstring), RLlib API."""

    def __init__(self, env_config: dict[str, Any] | None = None):
        super().__init__()  # type: ignore[no-untyped-call]  # RLlib leaves MultiAgentEnv.__init__ unannotated
        env_config = dict(env_config or {})
        self.with_global_state = bool(env_config.pop("with_global_state", False))
        self.config = GameConfig(**env_config)
        self.game = SingleGame(self.config)
        self.possible_agents = list(AGENTS)
        self.agents = list(AGENTS)
        self.action_spaces = {agent: self.game.action_spaces[agent] for agent in AGENTS}
        space = policy_input_space if self.with_global_state else observation_space
        self.observation_spaces = {agent: space(self.config, agent) for agent in AGENTS}

    def _observe(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        if not self.with_global_state:
            return obs
        state = self.game.state()
        return {agent: policy_input(o, state) for agent, o in obs.items()}

    # RLlib keys its dicts by ``AgentID`` (``Hashable | str``); this env's agents are the names of
    # ``AGENTS``, and a dict is invariant in its key type: hence the two ``override`` ignores.
    def reset(  # type: ignore[override]
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        self.agents = list(AGENTS)
        obs, infos = self.game.reset(seed, (options or {}).get("positions"))
        return self._observe(obs), infos

    def step(  # type: ignore[override]
        self, action_dict: dict[str, np.ndarray]
    ) -> tuple[dict[str, np.ndarray], dict[str, float], dict[str, bool], dict[str, bool], dict[str, dict[str, Any]]]:
        obs, rewards, done, infos = self.game.step(action_dict)
        terminateds = {agent: done for agent in AGENTS}
        terminateds["__all__"] = done
        truncateds = {agent: False for agent in AGENTS}
        truncateds["__all__"] = False
        if done:
            self.agents = []
        return self._observe(obs), rewards, terminateds, truncateds, infos
