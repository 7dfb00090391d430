"""Mixture players: a side's Nash mixture of the league's meta-game, played as one player that
draws one member per game.

| name | what it is |
| ---- | ---------- |
| ``nash-attacker``, ``nash-team`` | the side's Nash mixture of the final meta-game (the one ``league.status`` shows) |
| ``nash-attacker@K``, ``nash-team@K`` | the same of iteration ``K``'s meta-game: the frozen players the league had after iteration ``K`` |

The members are the players the side's mixture weighs (its support), with their weights. Where
the Nash equilibrium is not unique the mixture is the LP's one vertex (``league.analysis.nash``),
always the same for the same results; each member's range (the least and the most weight any
optimal mixture gives it) says how much of its weight is the game's and how much the LP's choice.

**The draw.** A mixture plays game ``g`` (a fixed game's index, or a game's number in the
caller's own sequence) with one member, fixed by ``(seed, side, g)`` alone: the same seed gives
the same members whatever the batching, the order or the slices the games are played in. With
``P = 2**31 - 1`` (prime) and integer arithmetic only (so torch, ONNX and NumPy compute the same
numbers; ``league.evaluation.exported_policy`` builds it into the exported module):

1. ``key = mix(mix(mix(seed) + stream) + g)``, ``stream`` 0 for attackers and 1 for teams (so a
   mixture against a mixture draws its two sides independently);
2. ``mix(x)``: ``x mod P``, then a round per key of ``MIX_KEYS``, ``x = (x (x + k) + c) mod P`` and
   ``x = 48271 x mod P`` (a quadratic step for nonlinearity, Park and Miller's multiplier to
   spread it; every product stays below ``2**63``);
3. member ``i`` is drawn where ``b[i-1] <= key < b[i]``, ``b[i] = round(P * (w[0] + ... + w[i]))``
   the weights' cumulative boundaries (the last one ``P``, never reached): the number of
   boundaries at or below ``key``.

``tests/core/test_mixture.py`` checks the keys are uniform and the members' frequencies match
the weights.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from league.core.players import Player, Side

MODULUS = 2**31 - 1  # P: a prime; x (x + k) < 2**63 for x < P and k < P
MIX_MULTIPLIER = 48271  # Park and Miller's minimal-standard multiplier modulo P
MIX_KEYS = (0x2545F491, 0x5851F42D, 0x14057B7E)  # k of each round (below 2**31)
MIX_INCREMENT = 0x1B873593  # c
SIDE_STREAMS = {"attacker": 0, "team": 1}
SEED_RANGE = (0, MODULUS - 1)  # seeds below P give distinct key sequences

MIXTURE_PREFIX = "nash"  # no player's name starts with it (league.core.players)
MIXTURE_SIDES: dict[str, Side] = {"nash-attacker": "attacker", "nash-team": "team"}
_NAME = re.compile(r"^(?P<base>[^@]+)(@(?P<iteration>.*))?$")

IntArray = npt.NDArray[np.int64]


class MixtureError(ValueError):
    """A mixture's name that names none, or a meta-game that has none; the message is one line for the user."""


def is_mixture_name(name: str) -> bool:
    """Whether ``name`` asks for a mixture player (rightly spelt or not): a player's name never starts with ``nash``."""
    return name.startswith(MIXTURE_PREFIX)


@dataclass(frozen=True)
class MixtureName:
    """A parsed mixture name: its side and the meta-game's iteration (``None``: the final one)."""

    side: Side
    iteration: int | None

    @property
    def name(self) -> str:
        base = f"nash-{self.side}"
        return base if self.iteration is None else f"{base}@{self.iteration}"


def parse_mixture_name(name: str) -> MixtureName:
    """``nash-attacker``, ``nash-team``, or either with ``@K`` (an iteration, an integer from 0)."""
    known = " or ".join(MIXTURE_SIDES)
    match = _NAME.match(name)
    if match is None or match["base"] not in MIXTURE_SIDES:
        raise MixtureError(f"{name!r} is no mixture player: {known}, optionally @ITERATION (e.g. nash-team@120)")
    iteration = match["iteration"]
    if iteration is not None and not (iteration.isdigit() and iteration.isascii()):
        raise MixtureError(f"{name!r}: the iteration after @ must be an integer from 0, got {iteration!r}")
    return MixtureName(MIXTURE_SIDES[match["base"]], None if iteration is None else int(iteration))


# ---------------------------------------------------------------- the draw
def mix(x: IntArray) -> IntArray:
    """Step 2 of the draw: ``x`` (any int64 at or above 0) to ``[0, P)``."""
    x = x % MODULUS
    for k in MIX_KEYS:
        x = (x * (x + k) + MIX_INCREMENT) % MODULUS
        x = (x * MIX_MULTIPLIER) % MODULUS
    return x


def draw_keys(seed: int, stream: int, games: npt.ArrayLike) -> IntArray:
    """Step 1: each game's key in ``[0, P)`` from (``seed``, ``stream``, the game's index)."""
    games = np.asarray(games, dtype=np.int64)
    if seed < 0 or (games < 0).any():
        raise ValueError("mixture seeds and game indices are integers from 0")
    return mix(mix(mix(np.asarray(seed, dtype=np.int64)) + stream) + games)


def boundaries(weights: list[float] | tuple[float, ...]) -> IntArray:
    """Step 3's boundaries ``b``: one per member, the last ``P``."""
    w = np.asarray(weights, dtype=np.float64)
    if w.size == 0 or (w < 0).any() or w.sum() <= 0:
        raise ValueError(f"a mixture needs at least one member and nonnegative weights, got {list(w)}")
    b = np.round(np.cumsum(w / w.sum()) * MODULUS).astype(np.int64)
    b[-1] = MODULUS
    return b


def member_indices(keys: IntArray, bounds: IntArray) -> IntArray:
    """Step 3: each key's member, the number of boundaries at or below it."""
    counted: IntArray = (keys[:, None] >= bounds[None, :]).sum(axis=1).astype(np.int64)
    return counted


# ---------------------------------------------------------------- the player
@dataclass(frozen=True)
class Mixture:
    """A side's Nash mixture as a player: its members (the support, heaviest first) and their weights."""

    name: str  # as asked for: nash-team, nash-team@120
    side: Side
    iteration: int  # the meta-game's: the last iteration for the final one
    members: tuple[Player, ...]
    weights: tuple[float, ...]  # the LP's vertex, summing to 1
    ranges: tuple[tuple[float, float], ...]  # each member's least and most weight over every optimal mixture
    value: float  # the side's meta-game value: its expected win rate against the other side's Nash mixture
    seed: int = 0  # what its per-game draws are made from (``--mixture-seed``): the same seed, the same members

    def __post_init__(self) -> None:
        if not (len(self.members) == len(self.weights) == len(self.ranges)) or not self.members:
            raise ValueError(f"{self.name}: one weight and one range per member, and at least one member")
        if any(p.side != self.side for p in self.members):
            raise ValueError(f"{self.name}: every member must be of the {self.side} side")

    @property
    def stream(self) -> int:
        return SIDE_STREAMS[self.side]

    def draw(self, seed: int, games: npt.ArrayLike) -> IntArray:
        """The index (into ``members``) of each game's member."""
        return member_indices(draw_keys(seed, self.stream, games), boundaries(self.weights))

    def member_of(self, seed: int, game: int) -> Player:
        return self.members[int(self.draw(seed, [game])[0])]

    def scripted_members(self) -> list[Player]:
        return [p for p in self.members if p.kind == "scripted"]

    def rows(self) -> list[list[str]]:
        """``MIXTURE_MEMBER_HEADER`` rows, one per member."""
        return [[self.name, p.name, f"{w:.3f}", f"{low:.3f} to {high:.3f}"]
                for p, w, (low, high) in zip(self.members, self.weights, self.ranges)]

    def line(self) -> str:
        members = ", ".join(f"{p.name} {w:.3f}" for p, w in zip(self.members, self.weights))
        return f"{self.name} (iteration {self.iteration}'s meta-game, value {self.value:.3f}): {members}"

    def as_json(self) -> dict[str, object]:
        return {
            "mixture": self.name, "side": self.side, "iteration": self.iteration, "value": self.value,
            "members": [{"player": p.name, "weight": w, "range": list(r)}
                        for p, w, r in zip(self.members, self.weights, self.ranges)],
        }


MIXTURE_MEMBER_HEADER = ["mixture", "member", "weight", "range over optimal mixtures"]
MIXTURE_MEMBER_NOTE = (
    "A mixture player draws one member per game from a seed (nash-attacker, nash-team; @K for iteration K's meta-game). "
    "Weight: the LP's vertex, which it plays; range: the least and the most weight any optimal mixture gives the member."
)

Contestant = Player | Mixture
"""Who plays a side of a game: a league member, or a mixture of them."""
