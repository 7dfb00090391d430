"""The league's meta-game: the two-player zero-sum game on the payoff matrix of its frozen players.

Rows are attackers, columns teams, an entry is the attacker's win rate in the pair's
newest evaluation; the team's win rate is one minus it, so the game is constant-sum
(zero-sum after subtracting 0.5). Its Nash equilibrium is two linear programs, solved
with ``scipy.optimize.linprog`` (HiGHS):

1. the attacker's mixture ``x`` maximises ``v`` subject to ``(x A)_j >= v`` for every
   team ``j``, ``sum x = 1``, ``x >= 0``;
2. the team's mixture ``y`` minimises ``w`` subject to ``(A y)_i <= w`` for every
   attacker ``i``, ``sum y = 1``, ``y >= 0``.

By the minimax theorem ``v = w``: the game's value, the attacker's win rate when both
sides play their Nash mixtures.

Nash-averaged ratings (Balduzzi et al. 2018, "Re-evaluating evaluation"): each player's
expected win rate against the other side's Nash mixture, ``(A y)_i`` for attacker ``i``
and ``1 - (x A)_j`` for team ``j``. No player beats the value (the attackers' ratings are
at most ``v``, the teams' at most ``1 - v``); the players in a Nash mixture's support
reach it. Balduzzi et al. pick the maximum-entropy equilibrium to make the ratings unique;
the LP gives one equilibrium (a vertex), so where equilibria are not unique the ratings of
players outside every support may differ from the maximum-entropy one's.

The Nash range of a group of one side's players: the least and the most total weight that
any optimal mixture of that side puts on them (``weight_range``). The optimal mixtures form
a face of the simplex, and the LP's mixture is one vertex of it: of ``[[0.9, 0.1], [0.1, 0.9],
[0.5, 0.5]]`` the LP returns rows (0.5, 0.5, 0), yet (0, 0, 1) is optimal too, and two
identical columns split their weight arbitrarily. A share of the Nash weight is a property of
the game only where its range is narrow. Two more LPs per group, after the value ``v``:

3. minimise, then maximise, ``sum_{i in S} x_i`` subject to ``(x A)_j >= v - FACE_TOLERANCE``
   for every team ``j``, ``sum x = 1``, ``x >= 0``; the team side's on ``1 - A^T``.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from league.core.payoff import OutcomeCount, aggregate
from league.core.players import POOL_KINDS, Player

# HiGHS's default primal and dual feasibility tolerances are 1e-7; a weight below ten
# times that is solver noise around zero, not part of the mixture.
SUPPORT_THRESHOLD = 1e-6
# How far below the value an expected payoff of a mixture on the optimal face may be. HiGHS
# meets each constraint to its primal feasibility tolerance (1e-7), so the value v of the
# first LP may overshoot the game's value by that much, and the face LPs may again miss
# their constraints by that much: with less slack than 2e-7 the true optimal face could be
# cut off (or the face LP declared infeasible). Ten times HiGHS's tolerance keeps it inside
# with room. The slack lets in mixtures within 1e-6 of optimal, which moves a range's ends by
# at most 1e-6 / g, g the payoff a player outside the face loses per unit of weight: below
# the 0.0005 that the three printed decimals show wherever g > 0.002, less than one game in
# the 200 to 1,000 of an evaluated pair.
FACE_TOLERANCE = 1e-6


@dataclass(frozen=True)
class NashEquilibrium:
    """A Nash equilibrium of the zero-sum game with ``payoff`` (the row player's win rate)."""

    payoff: np.ndarray  # (rows, columns)
    row_mixture: np.ndarray  # attackers
    column_mixture: np.ndarray  # teams
    value: float  # the row player's expected payoff at the equilibrium

    @property
    def row_ratings(self) -> np.ndarray:
        """Each row's expected payoff against the column mixture."""
        return self.payoff @ self.column_mixture

    @property
    def column_ratings(self) -> np.ndarray:
        """Each column's expected payoff (one minus the row's) against the row mixture."""
        return 1.0 - self.row_mixture @ self.payoff


def _maximin(payoff: np.ndarray) -> tuple[np.ndarray, float]:
    """The row player's maximin mixture and value of ``payoff`` (row player maximises)."""
    from scipy.optimize import linprog  # here: seconds to import, and league.status often has no game to solve

    rows, columns = payoff.shape
    # Variables (x_1 .. x_rows, v); minimise -v.
    cost = np.zeros(rows + 1)
    cost[-1] = -1.0
    a_ub = np.hstack([-payoff.T, np.ones((columns, 1))])  # v - (x A)_j <= 0
    a_eq = np.hstack([np.ones((1, rows)), np.zeros((1, 1))])
    bounds = [(0.0, None)] * rows + [(None, None)]
    result = linprog(cost, A_ub=a_ub, b_ub=np.zeros(columns), A_eq=a_eq, b_eq=[1.0], bounds=bounds, method="highs")
    if result.status != 0:
        raise RuntimeError(f"the meta-game LP failed: {result.message}")
    mixture = np.clip(result.x[:rows], 0.0, None)
    mixture[mixture < SUPPORT_THRESHOLD] = 0.0
    return mixture / mixture.sum(), float(result.x[-1])


def _checked(payoff: np.ndarray) -> np.ndarray:
    payoff = np.asarray(payoff, dtype=float)
    if payoff.ndim != 2 or 0 in payoff.shape:
        raise ValueError(f"the payoff matrix must be 2-D and non-empty, got shape {payoff.shape}")
    if not np.all(np.isfinite(payoff)):
        raise ValueError("the payoff matrix has missing (NaN) or infinite entries")
    return payoff


def solve_zero_sum(payoff: np.ndarray) -> NashEquilibrium:
    """Each side's Nash mixture and the value of the zero-sum game with ``payoff`` (entries in [0, 1])."""
    payoff = _checked(payoff)
    rows, value = _maximin(payoff)
    # The column player maximises its own payoff 1 - A, i.e. minimises the row player's.
    columns, column_value = _maximin(1.0 - payoff.T)
    if abs(value - (1.0 - column_value)) > 10 * SUPPORT_THRESHOLD:
        raise RuntimeError(f"the two LPs disagree on the value: {value} vs {1.0 - column_value}")
    return NashEquilibrium(payoff, rows, columns, value)


def weight_range(payoff: np.ndarray, side: Literal["row", "column"], members: Iterable[int]) -> tuple[float, float]:
    """The least and the most total weight that an optimal mixture of ``side`` puts on ``members``
    (row or column indices) in the zero-sum game with ``payoff`` (the row player's payoff, in [0, 1])."""
    from scipy.optimize import linprog

    payoff = _checked(payoff)
    game = payoff if side == "row" else 1.0 - payoff.T  # the side as the maximising row player
    _, value = _maximin(game)
    strategies, opponents = game.shape
    in_group = np.zeros(strategies)
    in_group[list(members)] = 1.0
    # The optimal face: x >= 0, sum x = 1 and (x G)_j >= value - FACE_TOLERANCE for every opponent j.
    face = dict(A_ub=-game.T, b_ub=np.full(opponents, FACE_TOLERANCE - value),
                A_eq=np.ones((1, strategies)), b_eq=[1.0], bounds=[(0.0, None)] * strategies, method="highs")
    ends = []
    for sign in (1.0, -1.0):  # minimise the group's weight, then maximise it
        result = linprog(sign * in_group, **face)
        if result.status != 0:
            raise RuntimeError(f"the meta-game's face LP failed: {result.message}")
        ends.append(float(np.clip(sign * result.fun, 0.0, 1.0)))
    return ends[0], ends[1]


# ---------------------------------------------------------------- the league's meta-game
# The groups whose Nash range the commands report, on each side (``weight_group``).
WEIGHT_GROUPS = {
    "learners": "trained learners' snapshots (v1 on)",
    "exploiters": "exploiters' snapshots",
    "oracles": "double-oracle best responses",
    "scripted_and_v0": "scripted players and v0",
}


def weight_group(player: Player) -> str:
    """A frozen player's group in ``WEIGHT_GROUPS``: a learner's snapshot from version 1 on, an
    exploiter's snapshot, a double-oracle best response, or the rest (scripted players, a learner's
    untrained version 0)."""
    if player.kind == "exploiter_snapshot":
        return "exploiters"
    if player.kind == "oracle":
        return "oracles"
    if player.kind == "snapshot" and player.version > 0:
        return "learners"
    return "scripted_and_v0"


@dataclass(frozen=True)
class GroupWeight:
    """One group's share of its side's Nash weight: at the LP's vertex, and over every optimal mixture."""

    side: str
    group: str  # a key of WEIGHT_GROUPS
    players: list[str]
    vertex: float  # the total weight of the LP's mixture (one optimal vertex)
    low: float  # the least total weight of any optimal mixture of the side
    high: float  # the most

    def row(self) -> list[str]:
        return [self.side, WEIGHT_GROUPS[self.group], str(len(self.players)), f"{self.vertex:.3f}",
                f"{self.low:.3f} to {self.high:.3f}"]

    def as_json(self) -> dict:
        return {"side": self.side, "group": self.group, "players": self.players, "vertex_weight": self.vertex,
                "range": [self.low, self.high]}


@dataclass(frozen=True)
class MetaGame:
    """The Nash equilibrium of the league's frozen attackers (rows) against its frozen teams (columns)."""

    attackers: list[Player]
    teams: list[Player]
    equilibrium: NashEquilibrium

    def ratings(self) -> dict[int, float]:
        """Nash-averaged rating by player id: its win rate against the other side's Nash mixture."""
        eq = self.equilibrium
        return {
            **{p.id: float(r) for p, r in zip(self.attackers, eq.row_ratings)},
            **{p.id: float(r) for p, r in zip(self.teams, eq.column_ratings)},
        }

    def weight_range(self, side: str, players: Iterable[Player]) -> tuple[float, float]:
        """The least and the most total weight an optimal mixture of ``side`` (attacker or team) puts on ``players``."""
        chosen = {p.id for p in players}
        members = [k for k, p in enumerate(self.attackers if side == "attacker" else self.teams) if p.id in chosen]
        return weight_range(self.equilibrium.payoff, "row" if side == "attacker" else "column", members)

    def group_weights(self) -> list[GroupWeight]:
        """Each side's ``WEIGHT_GROUPS``, empty ones included: the vertex's weight and the Nash range."""
        eq, found = self.equilibrium, []
        sides = (("attacker", self.attackers, eq.row_mixture), ("team", self.teams, eq.column_mixture))
        for side, players, weights in sides:
            for group in WEIGHT_GROUPS:
                members = [(p, w) for p, w in zip(players, weights) if weight_group(p) == group]
                low, high = self.weight_range(side, [p for p, _ in members]) if members else (0.0, 0.0)
                found.append(GroupWeight(side, group, [p.name for p, _ in members], float(sum(w for _, w in members)),
                                         low, high))
        return found

    def group_rows(self) -> list[list[str]]:
        """``GROUP_HEADER`` rows of the groups with players."""
        return [g.row() for g in self.group_weights() if g.players]

    def mixture_rows(self) -> list[list[str]]:
        """``[side, player, Nash weight, Nash-averaged rating]`` of the players with nonzero weight."""
        eq, rows = self.equilibrium, []
        for side, players, weights, ratings in (
            ("attacker", self.attackers, eq.row_mixture, eq.row_ratings),
            ("team", self.teams, eq.column_mixture, eq.column_ratings),
        ):
            for k in np.argsort(-weights, kind="stable"):
                if weights[k] > 0:
                    rows.append([side, players[k].name, f"{weights[k]:.3f}", f"{ratings[k]:.3f}"])
        return rows

    def as_json(self) -> dict:
        """The value, every player's Nash weight (at the LP's vertex) and Nash-averaged rating, and each
        group's weight at the vertex and Nash range (``--json`` of the commands)."""
        eq = self.equilibrium
        players = [
            {"side": side, "player": p.name, "nash_weight": float(w), "nash_averaged_rating": float(r)}
            for side, group, weights, ratings in (
                ("attacker", self.attackers, eq.row_mixture, eq.row_ratings),
                ("team", self.teams, eq.column_mixture, eq.column_ratings),
            )
            for p, w, r in zip(group, weights, ratings)
        ]
        return {"value": float(eq.value), "players": players, "groups": [g.as_json() for g in self.group_weights()]}

    def value_line(self) -> str:
        value = self.equilibrium.value
        return (
            f"Meta-game of {len(self.attackers)} attackers x {len(self.teams)} teams: value {value:.3f} (the attacker's "
            f"win rate when both sides play their Nash mixtures; the team's is {1 - value:.3f})."
        )


GROUP_TITLE = "Nash weight by group"
GROUP_HEADER = ["side", "group", "players", "weight at the vertex", "range over optimal mixtures"]
GROUP_NOTE = (
    "Range: the least and the most weight that any optimal (maximin) mixture of the side puts on the group; "
    "where it is wide, the group's share is the LP's choice, not the game's."
)
MIXTURE_TITLE = "Nash mixture (one optimal vertex, as the LP found it)"
MIXTURE_HEADER = ["side", "player", "Nash weight", "Nash-averaged rating"]
META_GAME_NOTE = (
    "Nash-averaged rating: the player's win rate against the other side's Nash mixture (Balduzzi et al. 2018); "
    "no player exceeds the value (attackers) or one minus it (teams)."
)


def meta_game_players(players: list[Player]) -> tuple[list[Player], list[Player]]:
    """The league's frozen attackers and teams: snapshots, exploiter snapshots, double-oracle best
    responses and scripted players (not learners, exploiters or ``league.exploit``'s best responses)."""
    frozen = [p for p in players if p.kind in (*POOL_KINDS, "scripted")]
    return [p for p in frozen if p.side == "attacker"], [p for p in frozen if p.side == "team"]


def missing_pairs(
    attackers: list[Player], teams: list[Player], payoff: dict[tuple[int, int], tuple[int, int]]
) -> list[tuple[Player, Player]]:
    """The pairs without an evaluated game in ``payoff`` (``{(attacker id, team id): (attacker wins, games)}``)."""
    return [(a, t) for a in attackers for t in teams if payoff.get((a.id, t.id), (0, 0))[1] == 0]


def meta_game(
    attackers: list[Player], teams: list[Player], payoff: dict[tuple[int, int], tuple[int, int]]
) -> MetaGame | None:
    """The meta-game of these players, or None when a pair was never evaluated (or a side is empty)."""
    if not attackers or not teams or missing_pairs(attackers, teams, payoff):
        return None
    matrix = np.array([[payoff[(a.id, t.id)][0] / payoff[(a.id, t.id)][1] for t in teams] for a in attackers])
    return MetaGame(attackers, teams, solve_zero_sum(matrix))


def _markdown_table(header: list[str], rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "| " + " | ".join("---" for _ in header) + " |",
            *("| " + " | ".join(row) + " |" for row in rows)]


def format_meta_game(meta: MetaGame | None, why_not: str = "") -> str:
    """Markdown: the value, each group's Nash weight and range, then the players with nonzero Nash weight."""
    if meta is None:
        return f"No meta-game: {why_not}\n"
    lines = [meta.value_line(), "", f"{GROUP_TITLE}:", "", *_markdown_table(GROUP_HEADER, meta.group_rows()), "",
             GROUP_NOTE, "", f"{MIXTURE_TITLE}:", "", *_markdown_table(MIXTURE_HEADER, meta.mixture_rows())]
    return "\n".join(lines + ["", META_GAME_NOTE]) + "\n"


def league_meta_game(players: list[Player], evaluation_rows: list[OutcomeCount]) -> tuple[MetaGame | None, str]:
    """The meta-game on each pair's newest evaluation (``LeagueStore.newest_evaluation_rows``), or why there is none."""
    attackers, teams = meta_game_players(players)
    payoff = aggregate(evaluation_rows)
    missing = missing_pairs(attackers, teams, payoff)
    if missing:
        return None, (f"{len(missing)} of {len(attackers) * len(teams)} pairs of frozen players not evaluated yet "
                      "(python -m league.evaluate plays them)")
    if not attackers or not teams:
        return None, "the league has no frozen attacker or no frozen team"
    return meta_game(attackers, teams, payoff), ""


def mixture_by_player(meta: MetaGame) -> dict[int, float]:
    """Each frozen player's weight in its side's Nash mixture, by player id (0 off the support)."""
    sides = ((meta.attackers, meta.equilibrium.row_mixture), (meta.teams, meta.equilibrium.column_mixture))
    return {p.id: float(w) if w > SUPPORT_THRESHOLD else 0.0 for players, mixture in sides for p, w in zip(players, mixture)}
