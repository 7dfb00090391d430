"""League members: who they are, which side they play, which RLModules play for them.

A player is a row of the ``players`` table (``league.state.store``); its module ids are
derived from its columns, never parsed back from names.

| kind       | what it is                                             | trained |
| ---------- | ------------------------------------------------------ | ------- |
| learner    | the side's learning module (``attacker`` or ``team``)  | yes     |
| snapshot   | a frozen copy of a learner at some iteration           | no      |
| scripted   | a scripted player of ``envs.scripted``                 | no      |
| exploiter  | the side's exploiter (config ``league.exploiters``): trains in its side's phases against the other side's newest snapshots only | yes |
| exploiter_snapshot | a frozen copy of an exploiter, in its side's pool like a snapshot | no |
| best_response | trained from scratch against one frozen player (its ``parent``) by ``league.training.best_response`` (``python -m league.exploit``); not in the training pool | no (frozen once trained) |

Names: ``attacker-m2``, ``team`` (learners), ``attacker-m2-v3``, ``team-v2`` (snapshots),
``attacker-m2-exploiter``, ``team-exploiter-v1`` (exploiters and their snapshots),
``team-br0`` (best responses), ``scripted-lead_intercept`` (scripted).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from envs.scripted import PAPER_TEAM

Side = Literal["attacker", "team"]
Kind = Literal["learner", "snapshot", "exploiter", "exploiter_snapshot", "scripted", "best_response"]
TRAINED_KINDS = ("learner", "exploiter")  # kinds whose module trains; every other kind is frozen
SNAPSHOT_KIND = {"learner": "snapshot", "exploiter": "exploiter_snapshot"}  # what a trained kind freezes into
POOL_KINDS = ("snapshot", "exploiter_snapshot")  # trained players frozen into a side's pool


def other_side(side: str) -> str:
    return "team" if side == "attacker" else "attacker"


@dataclass(frozen=True)
class Player:
    id: int
    side: Side
    kind: Kind
    version: int
    reward_method: int | None = None
    parent: int | None = None
    scripted_attacker: str | None = None
    scripted_targeter: str | None = None
    scripted_defender: str | None = None
    env_steps: int = 0
    checkpoint: str | None = None
    created_iteration: int = 0
    seed: int | None = None  # a best response's training seed
    env_step_budget: int | None = None  # a best response's training budget (env steps asked for)
    from_prior: bool | None = None  # a best response: started from the run's prior (True) or from scratch (False)

    @property
    def trains(self) -> bool:
        """A learner or an exploiter: its module is trained in its side's phases."""
        return self.kind in TRAINED_KINDS

    @property
    def name(self) -> str:
        """Display name, also the module id of learners and snapshots.

        Attackers carry their reward method (``attacker-m2``, ``attacker-m2-v3``): a league
        may train attackers of several methods side by side.
        """
        if self.kind == "scripted":
            if self.side == "attacker":
                return f"scripted-{self.scripted_attacker}"
            return f"scripted-{self.scripted_targeter}+{self.scripted_defender}"
        base = f"attacker-m{self.reward_method}" if self.side == "attacker" else "team"
        if self.kind == "best_response":
            return f"{base}-br{self.version}"
        if self.kind in ("exploiter", "exploiter_snapshot"):
            base += "-exploiter"
        return base if self.trains else f"{base}-v{self.version}"

    @property
    def is_paper_team(self) -> bool:
        """The scripted team the paper trains its attackers against (``envs.scripted.PAPER_TEAM``)."""
        return self.kind == "scripted" and self.side == "team" and {
            "targeter": self.scripted_targeter, "defender": self.scripted_defender
        } == PAPER_TEAM

    def scripted_players(self) -> dict[str, str]:
        """``envs.scripted`` player name per agent of a scripted player's side (from its columns)."""
        if self.kind != "scripted":
            raise ValueError(f"{self.name} is not a scripted player")
        if self.side == "attacker":
            columns = {"attacker": self.scripted_attacker}
        else:
            columns = {"targeter": self.scripted_targeter, "defender": self.scripted_defender}
        missing = [f"scripted_{agent}" for agent, name in columns.items() if name is None]
        if missing:
            raise ValueError(f"scripted player {self.id} has no {' nor '.join(missing)}")
        return {agent: name for agent, name in columns.items() if name is not None}

    def modules(self) -> dict[str, str]:
        """Module id per agent for the agents of this player's side."""
        if self.kind == "scripted":
            return {agent: f"scripted-{agent}-{name}" for agent, name in self.scripted_players().items()}
        agents = ("attacker",) if self.side == "attacker" else ("targeter", "defender")
        return {agent: self.name for agent in agents}
