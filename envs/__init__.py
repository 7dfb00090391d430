"""The 3D cooperative target defense game: batched core, scripted players and adapters.

Nothing here knows about training. Import the adapters from their modules
(``envs.pettingzoo_env``, ``envs.rllib_env``, ``envs.vector_env``) so that RLlib is only
loaded when needed.
"""

from envs.agents import AGENTS, Outcome
from envs.config import GameConfig
from envs.core import BatchedGame

__all__ = ["AGENTS", "BatchedGame", "GameConfig", "Outcome"]
