"""Anytime PSRO's meta-solver (``league.double_oracle.meta_solver: regret_matching``): each side's
restricted distribution by regret matching against the other side's best responses.

PSRO's Nash mixture of the restricted game can be more exploitable after a phase than before:
the new members change the equilibrium, and nothing ties it to what a best response in the
full game could do. Anytime double oracle (McAleer et al. 2022, "Anytime PSRO for two-player
zero-sum games") instead gives each side the distribution over its members that is least
exploitable in the full game; since the old distribution stays available as the members grow,
that exploitability cannot rise from one iteration to the next. It finds the distribution by
regret matching against best responses (RM-BR): a no-regret learner over the side's members,
its opponent at every round a best response to its current strategy.

Here the full game's best responses are the other side's double-oracle best responses (kind
``oracle``: each trained against this side's distribution of its time, the strongest opponents
of it the league has), and each round's opponent is the one of them that does best against the
current strategy:

1. the regrets start at 0; a round's strategy ``s`` is the regrets' positive part, normalised
   (uniform while none is positive: Hart and Mas-Colell's regret matching);
2. the opponent is the best response ``j`` with the least payoff ``(s A)_j`` for the side (its
   win rate, ``A`` the pair's newest evaluations; ties: the oldest);
3. each member ``i``'s regret grows by ``A[i, j] - (s A)_j``;
4. after ``ITERATIONS`` rounds the distribution is the rounds' average strategy, whose worst case
   against the best responses is within ``O(sqrt(members / rounds))`` of the least possible
   (``tests/analysis/test_regret_matching.py`` checks it against the linear program).

A side whose opponents have no best response yet plays its members uniformly.
"""

from __future__ import annotations

import numpy as np

from league.analysis.nash import SUPPORT_THRESHOLD, MetaGame

ITERATIONS = 20_000  # rounds: a worst case within 0.005 of the LP's on the games the tests draw (milliseconds each)


def regret_matching(payoff: np.ndarray, iterations: int = ITERATIONS) -> np.ndarray:
    """The row player's average strategy of regret matching against a column player that best
    responds every round, in the game where ``payoff[i, j]`` is the row player's payoff (steps 1-4)."""
    payoff = np.asarray(payoff, dtype=float)
    rows = payoff.shape[0]
    regrets, total = np.zeros(rows), np.zeros(rows)
    for _ in range(iterations):
        positive = np.maximum(regrets, 0.0)
        strategy = positive / positive.sum() if positive.sum() > 0 else np.full(rows, 1.0 / rows)
        total += strategy
        values = strategy @ payoff
        best = int(np.argmin(values))
        regrets += payoff[:, best] - values[best]
    return total / iterations


def restricted_distributions(meta: MetaGame, iterations: int = ITERATIONS) -> dict[int, float]:
    """Each frozen player's weight in its side's distribution, by player id (0 below ``SUPPORT_THRESHOLD``)."""
    payoff = meta.equilibrium.payoff  # the attacker's win rate, attackers by teams
    sides = (
        (meta.attackers, payoff, [j for j, p in enumerate(meta.teams) if p.kind == "oracle"]),
        (meta.teams, 1.0 - payoff.T, [i for i, p in enumerate(meta.attackers) if p.kind == "oracle"]),
    )
    weights: dict[int, float] = {}
    for players, game, responses in sides:
        mixture = (regret_matching(game[:, responses], iterations) if responses
                   else np.full(len(players), 1.0 / len(players)))
        mixture[mixture < SUPPORT_THRESHOLD] = 0.0
        mixture /= mixture.sum()
        weights.update({p.id: float(w) for p, w in zip(players, mixture)})
    return weights
