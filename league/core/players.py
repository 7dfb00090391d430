"""League members: who they are, which side they play, which RLModules play for them.

A player is a row of the ``players`` table (``league.state.store``); before the store gives
it one it is a ``NewPlayer`` (the same columns but the id and the iteration it joined). Its
module ids are derived from its columns, never parsed back from names.

What a member does is its role, a class per value of the store's ``kind`` column
(``ROLES``; ``Player.role``):

| role (kind)        | what it is                                             | trained |
| ------------------ | ------------------------------------------------------ | ------- |
| ``Learner`` (learner) | the side's learning module (``attacker`` or ``team``) | yes  |
| ``Snapshot`` (snapshot) | a frozen copy of a learner at some iteration, in its side's pool | no |
| ``Scripted`` (scripted) | a scripted player of ``envs.scripted``            | no      |
| ``Exploiter`` (exploiter) | the side's exploiter (config ``league.exploiters``): trains in its side's phases against the other side's newest snapshots only | yes |
| ``ExploiterSnapshot`` (exploiter_snapshot) | a frozen copy of an exploiter, in its side's pool like a snapshot | no |
| ``BestResponse`` (best_response) | trained from scratch against one frozen player (its ``parent``) by ``league.training.best_response`` (``python -m league.exploit``); not in the training pool | no (frozen once trained) |
| ``Oracle`` (oracle) | PSRO's best response, trained at a self-play phase's end against the other side's meta-strategy (``league.double_oracle``, ``league.training.oracle``); in its side's pool like a snapshot | no (frozen once trained) |

A new kind of member is a ``Role`` subclass with its ``kind`` and what differs (its name,
whether it trains or is in the pool, its modules), listed in ``ROLES``.

Names: ``attacker-m2``, ``team`` (learners), ``attacker-m2-v3``, ``team-v2`` (snapshots),
``attacker-m2-exploiter``, ``team-exploiter-v1`` (exploiters and their snapshots),
``team-br0`` (best responses), ``attacker-m2-oracle-v1`` (double-oracle best responses),
``scripted-lead_intercept`` (scripted).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, ClassVar, Literal, Protocol

from envs.scripted import PAPER_TEAM

Side = Literal["attacker", "team"]
Kind = Literal["learner", "snapshot", "exploiter", "exploiter_snapshot", "scripted", "best_response", "oracle"]
AGENTS_OF_SIDE: dict[str, tuple[str, ...]] = {"attacker": ("attacker",), "team": ("targeter", "defender")}
UNRECORDED_ID = -1  # the id of a player that is evaluated before its row is written (``NewPlayer.unrecorded``)


def other_side(side: str) -> str:
    return "team" if side == "attacker" else "attacker"


class Columns(Protocol):
    """What a role reads of a member: the columns of a ``Player`` or a ``NewPlayer``."""

    @property
    def side(self) -> Side: ...
    @property
    def version(self) -> int: ...
    @property
    def reward_method(self) -> int | None: ...
    @property
    def scripted_attacker(self) -> str | None: ...
    @property
    def scripted_targeter(self) -> str | None: ...
    @property
    def scripted_defender(self) -> str | None: ...


def base_name(player: Columns) -> str:
    """Attackers carry their reward method (``attacker-m2``): a league may train attackers of several methods side by side."""
    return f"attacker-m{player.reward_method}" if player.side == "attacker" else "team"


class Role:
    """What a kind of league member is: its name, whether it trains, whether it is in its side's pool."""

    kind: ClassVar[Kind]
    trains: ClassVar[bool] = False  # its module trains in its side's phases
    in_pool: ClassVar[bool] = False  # a frozen trained player among the other side's learners' opponents
    frozen_as: ClassVar[Kind | None] = None  # a trained role: the kind of its snapshots
    first_snapshot: ClassVar[int] = 0  # a trained role: the version of its first snapshot
    suffix: ClassVar[str] = "-v{version}"  # what follows the side's base name (``base_name``) in its players' names

    def name(self, player: Columns) -> str:
        """Display name, also the module id of learned players."""
        return base_name(player) + self.suffix.format(version=player.version)

    def modules(self, player: Columns) -> dict[str, str]:
        """Module id per agent of the player's side: one module plays all of them."""
        return {agent: self.name(player) for agent in AGENTS_OF_SIDE[player.side]}


class Learner(Role):
    kind = "learner"
    trains = True
    frozen_as = "snapshot"
    first_snapshot = 0  # its untrained policy, frozen when the run begins
    suffix = ""


class Snapshot(Role):
    kind = "snapshot"
    in_pool = True


class Exploiter(Role):
    kind = "exploiter"
    trains = True
    frozen_as = "exploiter_snapshot"
    first_snapshot = 1  # after its first phase: its untrained policy never joins the pool
    suffix = "-exploiter"


class ExploiterSnapshot(Role):
    kind = "exploiter_snapshot"
    in_pool = True
    suffix = "-exploiter-v{version}"


class BestResponse(Role):
    kind = "best_response"
    suffix = "-br{version}"


class Oracle(Role):
    """Version ``k``: the best response after its side's ``k``-th self-play phase, like that phase's snapshot."""

    kind = "oracle"
    in_pool = True
    suffix = "-oracle-v{version}"


class Scripted(Role):
    kind = "scripted"

    def name(self, player: Columns) -> str:
        if player.side == "attacker":
            return f"scripted-{player.scripted_attacker}"
        return f"scripted-{player.scripted_targeter}+{player.scripted_defender}"

    @staticmethod
    def players(player: Columns) -> dict[str, str]:
        """``envs.scripted`` player name per agent of the player's side (from its columns)."""
        if player.side == "attacker":
            columns = {"attacker": player.scripted_attacker}
        else:
            columns = {"targeter": player.scripted_targeter, "defender": player.scripted_defender}
        missing = [f"scripted_{agent}" for agent, name in columns.items() if name is None]
        if missing:
            raise ValueError(f"scripted player {Scripted().name(player)} has no {' nor '.join(missing)}")
        return {agent: name for agent, name in columns.items() if name is not None}

    def modules(self, player: Columns) -> dict[str, str]:
        return {agent: f"scripted-{agent}-{name}" for agent, name in self.players(player).items()}


ROLES: dict[str, Role] = {role.kind: role for role in (
    Learner(), Snapshot(), Exploiter(), ExploiterSnapshot(), BestResponse(), Oracle(), Scripted(),
)}
# The kinds by what their role does (readers that filter a list of players by kind).
TRAINED_KINDS = tuple(kind for kind, role in ROLES.items() if role.trains)
SNAPSHOT_KIND = {kind: role.frozen_as for kind, role in ROLES.items() if role.frozen_as is not None}
POOL_KINDS = tuple(kind for kind, role in ROLES.items() if role.in_pool)


def role_of(kind: str) -> Role:
    try:
        return ROLES[kind]
    except KeyError:
        raise ValueError(f"unknown kind of player {kind!r} (known: {', '.join(ROLES)})") from None


class _Member:
    """What a member is by its columns and its role, with or without a row."""

    side: Side
    kind: Kind
    version: int
    reward_method: int | None
    scripted_attacker: str | None
    scripted_targeter: str | None
    scripted_defender: str | None

    @property
    def role(self) -> Role:
        return role_of(self.kind)

    @property
    def trains(self) -> bool:
        """A learner or an exploiter: its module is trained in its side's phases."""
        return self.role.trains

    @property
    def name(self) -> str:
        """Display name, also the module id of learners and snapshots."""
        return self.role.name(self)

    @property
    def is_scripted(self) -> bool:
        return isinstance(self.role, Scripted)

    @property
    def is_paper_team(self) -> bool:
        """The scripted team the paper trains its attackers against (``envs.scripted.PAPER_TEAM``)."""
        return self.is_scripted and self.side == "team" and {
            "targeter": self.scripted_targeter, "defender": self.scripted_defender
        } == PAPER_TEAM

    def scripted_players(self) -> dict[str, str]:
        """``envs.scripted`` player name per agent of a scripted player's side (from its columns)."""
        if not self.is_scripted:
            raise ValueError(f"{self.name} is not a scripted player")
        return Scripted.players(self)

    def modules(self) -> dict[str, str]:
        """Module id per agent for the agents of this player's side."""
        return self.role.modules(self)


@dataclass(frozen=True)
class NewPlayer(_Member):
    """A league member before it has a row: what ``LeagueStore.add_player`` records."""

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
    seed: int | None = None  # a best response's training seed
    env_step_budget: int | None = None  # a best response's training budget (env steps asked for)
    from_prior: bool | None = None  # a best response: started from the run's prior (True) or from scratch (False)

    def __post_init__(self) -> None:
        role_of(self.kind)  # an unknown kind is an error here, not a wrong name later

    def columns(self) -> dict[str, Any]:
        return asdict(self)

    def unrecorded(self) -> Player:
        """This member as a ``Player`` with ``UNRECORDED_ID``: evaluated before its row is written
        (the evaluation's rows take the id the store gives it)."""
        return Player(id=UNRECORDED_ID, **self.columns())


@dataclass(frozen=True, kw_only=True)
class Player(NewPlayer):
    """A league member with its row: its columns, the id the store gave it and the iteration that created it."""

    id: int
    created_iteration: int = 0

    @property
    def in_pool(self) -> bool:
        """A frozen trained player (a snapshot, an exploiter's snapshot, an oracle): an opponent of the other side's learners."""
        return self.role.in_pool
