"""Who wins, win rates and ratings from game outcomes (rows of ``league.state.store``).

The one home of "who won": ``ATTACKER_WINS`` (the outcome labels the attacker wins, from
``envs.agents.Outcome.attacker_wins``) and the flip to one side's point of view
(``wins_of``, ``record_against``, ``winner``); every other module asks these. Results travel
as ``OutcomeCount`` rows, the store's ``matches`` table grouped by pair and outcome.

A pair never played counts as an even match (win rate 0.5), as in AlphaStar.
Ratings are Elo-scaled Bradley-Terry strengths fitted to all results so far:
``P(i beats j) = 1 / (1 + 10 ** ((r_j - r_i) / 400))``, mean rating 1000 over the rated
players. A player without a single game has nothing to fit and gets no rating (rather
than the prior's 1000, which would read as a measured average).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from envs.agents import ATTACKER_WIN_VALUES, Outcome

ATTACKER_WINS = frozenset(o.label for o in Outcome if o.attacker_wins)

UNPLAYED_WIN_RATE = 0.5
ELO_SCALE = 400.0 / np.log(10.0)
MEAN_RATING = 1000.0
# A weak prior (one draw against an average player) keeps unbeaten players finite.
PRIOR_GAMES = 1.0

Counts = TypeVar("Counts", int, np.ndarray)  # a count of games, or counts per game


def win_rate(wins: int, games: int) -> float:
    return wins / games if games else UNPLAYED_WIN_RATE


def attacker_won(outcome: str) -> bool:
    """Whether the attacker won a game that ended with the ``Outcome`` label ``outcome``."""
    return outcome in ATTACKER_WINS


def attacker_won_games(outcomes: np.ndarray) -> np.ndarray:
    """Per game, whether the attacker won: ``outcomes`` are ``Outcome`` values (ints), as the
    batched game and the rollout's rows hold them."""
    return np.isin(outcomes, ATTACKER_WIN_VALUES)


def winner(outcome: str) -> str:
    """The side (``attacker`` or ``team``) that won a game ended with the ``Outcome`` label ``outcome``."""
    return "attacker" if attacker_won(outcome) else "team"


def wins_of(side: str, attacker_wins: Counts, games: int | Counts) -> Counts:
    """Wins of ``side`` among ``games`` of which the attacker won ``attacker_wins``.

    Counts or numpy arrays of counts (``games`` 1 and 0/1 wins for single games).
    """
    wins: Counts = attacker_wins if side == "attacker" else games - attacker_wins
    return wins


@dataclass(frozen=True)
class OutcomeCount:
    """``count`` games of the attacker player ``attacker`` against the team player ``team``
    (player ids) that ended with ``outcome`` (an ``envs.agents.Outcome`` label)."""

    attacker: int
    team: int
    outcome: str
    count: int

    @property
    def attacker_won(self) -> bool:
        return attacker_won(self.outcome)

    def wins(self, side: str) -> int:
        """Games of these that ``side`` won (all or none of them)."""
        return wins_of(side, self.count if self.attacker_won else 0, self.count)


def pair_key(side: str, player: int, opponent: int) -> tuple[int, int]:
    """The ``(attacker, team)`` key of a game between ``player`` (on ``side``) and ``opponent``."""
    return (player, opponent) if side == "attacker" else (opponent, player)


def record_against(table: dict[tuple[int, int], tuple[int, int]], side: str, player: int, opponent: int) -> tuple[int, int]:
    """``(wins, games)`` of ``player`` (on ``side``) against ``opponent`` in an ``aggregate`` table."""
    attacker_wins, games = table.get(pair_key(side, player, opponent), (0, 0))
    return wins_of(side, attacker_wins, games), games


def player_record(table: dict[tuple[int, int], tuple[int, int]], side: str, player: int) -> tuple[int, int]:
    """``(wins, games)`` of ``player`` (on ``side``) against everyone in an ``aggregate`` table."""
    wins = games = 0
    for (attacker, team), (attacker_wins, n) in table.items():
        if player == (attacker if side == "attacker" else team):
            wins, games = wins + wins_of(side, attacker_wins, n), games + n
    return wins, games


def elo_ratings(results: list[tuple[int, int, int, int]], players: list[int], iterations: int = 200) -> dict[int, float]:
    """Ratings from ``(attacker_id, team_id, attacker_wins, games)`` rows, of the ``players`` that played."""
    played = {p for a, t, _, n in results if n > 0 for p in (a, t)}
    players = [p for p in players if p in played]
    if not players:
        return {}
    index = {p: i for i, p in enumerate(players)}
    wins = np.zeros((len(players), len(players)))
    games = np.zeros_like(wins)
    for attacker, team, attacker_wins, n in results:
        if attacker not in index or team not in index:
            continue
        a, t = index[attacker], index[team]
        wins[a, t] += attacker_wins
        wins[t, a] += n - attacker_wins
        games[a, t] += n
        games[t, a] += n
    strength = np.zeros(len(players))
    total_wins = wins.sum(axis=1) + PRIOR_GAMES / 2
    for _ in range(iterations):  # minorise-maximise updates of Bradley-Terry (Hunter 2004)
        expo = np.exp(strength)
        denom = (games / (expo[:, None] + expo[None, :] + 1e-300)).sum(axis=1) + PRIOR_GAMES / (expo + 1.0)
        strength = np.log(total_wins / denom)
        strength -= strength.mean()
    return {p: float(MEAN_RATING + ELO_SCALE * strength[index[p]]) for p in players}


def aggregate(rows: list[OutcomeCount]) -> dict[tuple[int, int], tuple[int, int]]:
    """``{(attacker, team): (attacker wins, games)}`` from outcome rows."""
    table: dict[tuple[int, int], list[int]] = defaultdict(lambda: [0, 0])
    for row in rows:
        entry = table[(row.attacker, row.team)]
        entry[1] += row.count
        entry[0] += row.wins("attacker")
    return {key: (w, n) for key, (w, n) in table.items()}


def league_ratings(outcome_rows: list[OutcomeCount], players: list[int]) -> dict[int, float]:
    """Ratings from outcome rows (``LeagueStore.counted_results``)."""
    table = aggregate(outcome_rows)
    return elo_ratings([(a, t, w, n) for (a, t), (w, n) in table.items()], players)
