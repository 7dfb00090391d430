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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from league.core.payoff import OutcomeCount, aggregate
from league.core.players import POOL_KINDS, Player

# HiGHS's default primal and dual feasibility tolerances are 1e-7; a weight below ten
# times that is solver noise around zero, not part of the mixture.
SUPPORT_THRESHOLD = 1e-6


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


def solve_zero_sum(payoff: np.ndarray) -> NashEquilibrium:
    """Each side's Nash mixture and the value of the zero-sum game with ``payoff`` (entries in [0, 1])."""
    payoff = np.asarray(payoff, dtype=float)
    if payoff.ndim != 2 or 0 in payoff.shape:
        raise ValueError(f"the payoff matrix must be 2-D and non-empty, got shape {payoff.shape}")
    if not np.all(np.isfinite(payoff)):
        raise ValueError("the payoff matrix has missing (NaN) or infinite entries")
    rows, value = _maximin(payoff)
    # The column player maximises its own payoff 1 - A, i.e. minimises the row player's.
    columns, column_value = _maximin(1.0 - payoff.T)
    if abs(value - (1.0 - column_value)) > 10 * SUPPORT_THRESHOLD:
        raise RuntimeError(f"the two LPs disagree on the value: {value} vs {1.0 - column_value}")
    return NashEquilibrium(payoff, rows, columns, value)


# ---------------------------------------------------------------- the league's meta-game
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
        """The value and every player's Nash weight and Nash-averaged rating (``--json`` of the commands)."""
        eq = self.equilibrium
        players = [
            {"side": side, "player": p.name, "nash_weight": float(w), "nash_averaged_rating": float(r)}
            for side, group, weights, ratings in (
                ("attacker", self.attackers, eq.row_mixture, eq.row_ratings),
                ("team", self.teams, eq.column_mixture, eq.column_ratings),
            )
            for p, w, r in zip(group, weights, ratings)
        ]
        return {"value": float(eq.value), "players": players}

    def value_line(self) -> str:
        value = self.equilibrium.value
        return (
            f"Meta-game of {len(self.attackers)} attackers x {len(self.teams)} teams: value {value:.3f} (the attacker's "
            f"win rate when both sides play their Nash mixtures; the team's is {1 - value:.3f})."
        )


MIXTURE_HEADER = ["side", "player", "Nash weight", "Nash-averaged rating"]
META_GAME_NOTE = (
    "Nash-averaged rating: the player's win rate against the other side's Nash mixture (Balduzzi et al. 2018); "
    "no player exceeds the value (attackers) or one minus it (teams)."
)


def meta_game_players(players: list[Player]) -> tuple[list[Player], list[Player]]:
    """The league's frozen attackers and teams: snapshots, exploiter snapshots and scripted players
    (not learners, exploiters or best responses)."""
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


def format_meta_game(meta: MetaGame | None, why_not: str = "") -> str:
    """Markdown: the value, then the players with nonzero Nash weight."""
    if meta is None:
        return f"No meta-game: {why_not}\n"
    lines = [meta.value_line(), "", "| " + " | ".join(MIXTURE_HEADER) + " |", "| " + " | ".join("---" for _ in MIXTURE_HEADER) + " |"]
    lines += ["| " + " | ".join(row) + " |" for row in meta.mixture_rows()]
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
