"""Prioritised fictitious self-play: how often the learner meets each candidate opponent.

``x`` is the learner's win rate against a candidate. AlphaStar's ``squared`` weighting
``(1 - x)^2`` favours opponents the learner still loses to; ``variance`` ``x (1 - x)``
favours even matches; ``uniform`` ignores ``x``. ``nash`` is PSRO's rule instead: the
opponents' weights are their side's Nash mixture in the meta-game of the league's frozen
players, given by the caller. If every weight is zero the choice falls back to uniform, so
the learner always has someone to play. ``with_scripted_share`` holds a fixed share of the
games for the scripted players (``league.scripted_share``).
"""

from __future__ import annotations

import numpy as np

WEIGHTINGS = {
    "squared": lambda x: (1.0 - x) ** 2,
    "variance": lambda x: x * (1.0 - x),
    "uniform": lambda x: np.ones_like(x),
}


def pfsp_probabilities(
    win_rates: np.ndarray | list[float], weighting: str = "squared", nash_weights: np.ndarray | list[float] | None = None
) -> np.ndarray:
    """Probabilities over candidates from the learner's win rates against them (``nash``: from
    ``nash_weights``, the candidates' Nash weights)."""
    x = np.asarray(win_rates, dtype=np.float64)
    if x.size == 0:
        raise ValueError("PFSP needs at least one candidate opponent")
    if weighting == "nash":
        if nash_weights is None or len(nash_weights) != x.size:
            raise ValueError("the nash weighting needs one Nash weight per candidate")
        weights = np.asarray(nash_weights, dtype=np.float64)
    else:
        weights = WEIGHTINGS[weighting](x)
    total = weights.sum()
    if total <= 0:
        return np.full(x.shape, 1.0 / x.size)
    probabilities: np.ndarray = weights / total
    return probabilities


def with_scripted_share(
    win_rates: np.ndarray | list[float], scripted: list[bool], share: float, weighting: str = "squared",
    nash_weights: np.ndarray | list[float] | None = None, scripted_weighting: str = "pfsp",
) -> np.ndarray:
    """PFSP probabilities with ``share`` of the mass held for the ``scripted`` candidates and
    spread over them by the same weighting (``scripted_weighting="uniform"``: evenly):
    ``(1 - share) p + share q``, ``q`` over the scripted ones alone. Plain PFSP where none is
    scripted."""
    p = pfsp_probabilities(win_rates, weighting, nash_weights)
    mask = np.asarray(scripted, dtype=bool)
    if share == 0 or not mask.any():
        return p
    q = np.zeros_like(p)
    q[mask] = pfsp_probabilities(
        np.asarray(win_rates, dtype=np.float64)[mask], weighting if scripted_weighting == "pfsp" else "uniform",
        None if nash_weights is None else np.asarray(nash_weights)[mask],
    )
    return (1.0 - share) * p + share * q
