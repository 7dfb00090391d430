"""How a learner is paid in training: its settings (``TrainingPay``) and the rewards it learns from.

The game pays every agent the paper's rewards (``envs.rewards``: Eq. 7-9 for the attacker,
under all three methods at once, and Eq. 10-11 for T and D). A learner may be paid otherwise
in training only; returns in curves, evaluations and metrics stay the game's:

| setting (``PPOSettings``)                | who      | paid                                                              |
| ---------------------------------------- | -------- | ----------------------------------------------------------------- |
| the player's reward method               | attacker | the env's reward under its own method (Eq. 7, 8 or 9)             |
| ``attacker_win_reward`` ``R``            | attacker | ``+R`` on the step it won a game, ``-R`` on the step it lost one  |
| ``team_reward: shared``                  | T and D  | ``r_T + r_D`` each, instead of its own                            |
| ``targeter_shaping`` ``k``               | T        | ``+ gamma Phi(s') - Phi(s)``, ``Phi = -k |T ter|``                |
| ``defender_shaping`` ``k``               | D        | ``+ gamma Phi(s') - Phi(s)``, ``Phi = -k |D A|``                  |

The fast sampler pays all of them (``league.rollout.train_batch.slot_batch``); the batched and
standard samplers only the reward method (RLlib's learner connector
``league.rllib.callbacks.AttackerRewardByMethod`` calls ``method_rewards``), so
``league.config.RunConfig`` refuses the others there. ``tests/test_layering.py`` checks that
no module outside ``league/rollout/`` (and ``envs/``, the game's rules) assembles a training reward.
"""

from __future__ import annotations

from typing import Literal, Self

import numpy as np
from pydantic import BaseModel, ConfigDict

from envs.agents import Outcome
from envs.config import GameConfig
from envs.observations import GLOBAL_STATE_SIZE, interception_distance, terminal_distance
from league.config import RunConfig, Side
from league.core.payoff import attacker_won_games
from league.rollout.games import Rows

# The distance each team agent's potential-based shaping measures (T: to the terminal, D: to A).
SHAPED_DISTANCE = {"targeter": terminal_distance, "defender": interception_distance}


class TrainingPay(BaseModel):
    """What a learner is paid in training, and the discount of its advantages (GAE)."""

    model_config = ConfigDict(extra="forbid", frozen=True, use_attribute_docstrings=True)

    reward_method: int | None
    """The attacker's reward method (Eq. 7, 8 or 9); ``None`` for the team."""
    gamma: float
    """The fast sampler's GAE discount (the team's may differ: ``PPOSettings.team_gamma``)."""
    lambda_: float
    """The fast sampler's GAE lambda."""
    targeter_shaping: float
    """``PPOSettings.targeter_shaping`` for the team, 0 for the attacker."""
    defender_shaping: float
    """``PPOSettings.defender_shaping`` for the team, 0 for the attacker."""
    attacker_win_reward: float
    """``PPOSettings.win_reward`` of the attacker's method, 0 for the team."""
    team_reward: Literal["own", "shared"]
    """``PPOSettings.team_reward`` for the team, ``own`` for the attacker."""

    @classmethod
    def of(cls, run: RunConfig, side: Side, reward_method: int | None = None) -> Self:
        """How the ``run`` pays its ``side`` learner (an attacker of ``reward_method``)."""
        gamma, lambda_ = run.ppo.discount(side)
        team = side == "team"
        return cls(
            reward_method=reward_method,
            gamma=gamma,
            lambda_=lambda_,
            targeter_shaping=run.ppo.targeter_shaping if team else 0.0,
            defender_shaping=run.ppo.defender_shaping if team else 0.0,
            attacker_win_reward=0.0 if team else run.ppo.win_reward(reward_method),
            team_reward=run.ppo.team_reward if team else "own",
        )

    def shaping_of(self, agent: str) -> float:
        """The potential-based shaping coefficient of ``agent``'s rewards (0: none)."""
        return {"targeter": self.targeter_shaping, "defender": self.defender_shaping}.get(agent, 0.0)


def method_rewards(attacker_rewards: np.ndarray, reward_method: int) -> np.ndarray:
    """The attacker's rewards under ``reward_method`` from the env's under all three (last axis: methods 1, 2, 3)."""
    return attacker_rewards[..., reward_method - 1]


def ended_steps(outcomes: np.ndarray) -> np.ndarray:
    """1.0 on the steps on which a game ended (any outcome but running), else 0.0."""
    return (outcomes != int(Outcome.RUNNING)).astype(np.float64)


def potential_shaping(potentials: np.ndarray, ended: np.ndarray, gamma: float) -> np.ndarray:
    """Shaping rewards ``gamma * Phi(s') - Phi(s)`` ``(T, G)`` from ``potentials`` ``(T + 1, G)``.

    ``potentials[t]`` is ``Phi`` of the state before step ``t``; the last row is the state
    after the last step. A game that ended on step ``t`` has potential 0 after it: that
    makes the shaping sum over a game ``-Phi(s_0)`` whatever the agent does, so it changes
    no policy's ranking (Ng, Harada and Russell 1999) while paying for progress at once.
    """
    following = np.where(ended.astype(bool), 0.0, potentials[1:])
    return gamma * following - potentials[:-1]


def learner_rewards(pay: TrainingPay, agent: str, rows: Rows, t: int, game: GameConfig) -> np.ndarray:
    """The rewards ``(t, G)`` a learner paid as ``pay`` learns from as ``agent`` on rows ``0..t - 1``
    of every game (whoever played them: the caller keeps its own)."""
    ended = ended_steps(rows.outcome[:t])
    if agent == "attacker" and pay.reward_method:
        rewards = method_rewards(rows.attacker_rewards[:t], pay.reward_method)
        if pay.attacker_win_reward:
            won = np.where(attacker_won_games(rows.outcome[:t]), 1.0, -1.0)
            rewards = rewards + pay.attacker_win_reward * won * ended
    elif pay.team_reward == "shared":
        rewards = rows.rewards["targeter"][:t] + rows.rewards["defender"][:t]
    else:
        rewards = rows.rewards[agent][:t]
    shaping = pay.shaping_of(agent)
    if agent in SHAPED_DISTANCE and shaping:
        distance = SHAPED_DISTANCE[agent](game, rows.observations[agent][: t + 1, :, -GLOBAL_STATE_SIZE:])
        rewards = rewards + potential_shaping(-shaping * distance, ended, pay.gamma)
    return rewards
