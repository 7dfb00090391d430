"""RLlib's hooks into episodes: the learner connector that pays each attacker its own reward
method, and the callback that counts finished episodes' outcomes (``bridge.episode_outcomes`` reads them)."""

from __future__ import annotations

from typing import Any

import numpy as np

from envs.agents import AGENTS
from league.rllib import compat
from league.rllib.modules import ActorCriticModule
from league.rllib.runner_metrics import log_outcome
from league.rollout.training_reward import method_rewards
from ray.rllib.callbacks.callbacks import RLlibCallback
from ray.rllib.connectors.connector_v2 import ConnectorV2


class AttackerRewardByMethod(ConnectorV2):
    """Learner connector: pays each attacker module the reward of its own method.

    The env reports A's reward under all three methods in its info
    (``attacker_rewards``); this lets attackers of different methods share one league. The
    batched and standard samplers' only training reward (``league.rollout.training_reward``).
    It runs after PPO's one-timestep extension, whose phantom last reward stays as is.
    """

    def __call__(self, *, rl_module: Any, batch: dict[str, Any], episodes: list[Any], **kwargs: Any) -> Any:
        for episode in episodes:
            attacker = episode.agent_episodes.get("attacker")
            module_id = episode.module_for("attacker")
            if attacker is None or module_id not in rl_module:
                continue
            module = rl_module[module_id]
            # A scripted attacker keeps what the env paid.
            method = module.settings.reward_method if isinstance(module, ActorCriticModule) else None
            real_steps = len(attacker) - 1  # the last step is PPO's phantom bootstrap step
            if not method or real_steps <= 0:
                continue
            infos = attacker.get_infos(slice(1, real_steps + 1))
            by_method = np.array([info["attacker_rewards"] for info in infos])
            compat.overwrite_rewards(attacker, method_rewards(by_method, method).tolist())
        return batch


class OutcomeRecorder(RLlibCallback):
    """Counts finished episodes by (attacker module, targeter module, defender module, outcome)."""

    def on_episode_end(self, *, episode, metrics_logger=None, **kwargs) -> None:
        # Every agent's last info names the outcome (the batched sampler keeps only the learners').
        outcome = next(iter(episode.agent_episodes.values())).get_infos(-1)["outcome"]
        log_outcome(metrics_logger, [episode.module_for(agent) for agent in AGENTS], outcome)
