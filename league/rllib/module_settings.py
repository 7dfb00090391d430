"""What a league module is built with and how its learner is paid: typed, validated, one home.

RLlib hands a module its settings as the ``model_config`` dict of its ``RLModuleSpec`` and
saves that dict with the module (checkpoints, ``players/``), so the dict stays at RLlib's
boundary: ``league.rllib.bridge`` builds it with ``as_model_config()``, and a module's
``setup`` parses it back with ``from_model_config``, the only place that reads it by key.
Every other reader reads ``module.settings`` by attribute (the fast sampler hands an
``ActorCriticSettings`` to ``league.rollout`` as the ``TrainingPay`` it is), and a misspelt,
missing or ill-typed key is an error naming it rather than a setting silently off.
"""

from __future__ import annotations

from typing import Any, Literal, Self

from pydantic import BaseModel, ConfigDict

from envs.config import GameConfig
from league.rollout.training_reward import TrainingPay

# RLlib's own keys: PPO adds them to the model_config of every module the algorithm builds
# (`PPOConfig._model_config_auto_includes`); our modules do not read them.
RLLIB_KEYS = frozenset({"vf_share_layers"})


class _Settings(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, use_attribute_docstrings=True)

    @classmethod
    def from_model_config(cls, model_config: dict[str, Any] | None) -> Self:
        """The settings of a module's ``model_config``: every key known, none missing but those with a default
        (settings added since, which modules saved before them did not have)."""
        given = {key: value for key, value in (model_config or {}).items() if key not in RLLIB_KEYS}
        unknown = sorted(set(given) - set(cls.model_fields))
        missing = sorted(key for key, field in cls.model_fields.items() if key not in given and field.is_required())
        if unknown or missing:
            problems = [f"unknown key {key!r}" for key in unknown] + [f"missing key {key!r}" for key in missing]
            raise ValueError(f"{cls.__name__} from a module's model_config: {', '.join(problems)}")
        return cls.model_validate(given)

    def as_model_config(self) -> dict[str, Any]:
        """The ``model_config`` dict of the module's ``RLModuleSpec``."""
        return self.model_dump()


class ActorCriticSettings(_Settings, TrainingPay):
    """An ``ActorCriticModule``: its networks, how it samples, and how its learner is paid
    (``TrainingPay``'s fields, which ``league.rollout`` reads: flat in the saved dict, as before)."""

    actor_inputs: int
    """Length of the agent's own observation; the global state follows it in the policy input."""
    critic: Literal["global", "local"]
    """The value network's input: the global state and the role (the team's) or the own observation."""
    hidden: tuple[int, ...]
    """Hidden layer sizes of the actor and the critic (``PPOSettings.hidden_of``)."""
    prior: str
    """``none`` or a name of ``league.rllib.modules.PRIORS`` (``PPOSettings.attacker_prior``, ``team_prior``)."""
    heading_cosines: bool
    """The actor also reads ``HeadingCosines`` (``PPOSettings.attacker_heading_cosines``)."""
    scripted_turns: bool = False
    """The actor also reads ``ScriptedTurns`` (``PPOSettings.attacker_scripted_turns``)."""
    game: GameConfig
    """The game, for the prior's speeds and turn limits."""
    bf16: bool
    """Asked for; the learner computes in bf16 where the CPU has it natively (``PPOSettings.bf16``)."""
    explore_when_frozen: bool
    """A frozen copy samples its actions in training (``LeagueSettings.frozen_players_explore``)."""


class ScriptedSettings(_Settings):
    """A ``ScriptedModule``: which scripted player of ``envs.scripted`` it is."""

    agent: str
    """The agent it plays (``attacker``, ``targeter`` or ``defender``)."""
    name: str
    """The scripted player's name in ``envs.scripted``."""
    game: GameConfig
    """The game it acts in."""
    actor_inputs: int
    """Length of the agent's own observation; the global state it reads follows it."""
