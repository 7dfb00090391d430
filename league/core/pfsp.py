"""Prioritised fictitious self-play: how often the learner meets each candidate opponent.

``x`` is the learner's win rate against a candidate. AlphaStar's ``squared`` weighting
``(1 - x)^2`` favours opponents the learner still loses to; ``variance`` ``x (1 - x)``
favours even matches; ``uniform`` ignores ``x``. If every weight is zero the choice
falls back to uniform, so the learner always has someone to play. ``with_scripted_share``
holds a fixed share of the games for the scripted players (``league.scripted_share``).
"""

from __future__ import annotations

import numpy as np

WEIGHTINGS = {
    "squared": lambda x: (1.0 - x) ** 2,
    "variance": lambda x: x * (1.0 - x),
    "uniform": lambda x: np.ones_like(x),
}


def pfsp_probabilities(win_rates: np.ndarray | list[float], weighting: str = "squared") -> np.ndarray:
    """Probabilities over candidates from the learner's win rates against them."""
    x = np.asarray(win_rates, dtype=np.float64)
    if x.size == 0:
        raise ValueError("PFSP needs at least one candidate opponent")
    weights = WEIGHTINGS[weighting](x)
    total = weights.sum()
    if total <= 0:
        return np.full(x.shape, 1.0 / x.size)
    return weights / total


def with_scripted_share(probabilities: np.ndarray, scripted: list[bool], share: float) -> np.ndarray:
    """``probabilities`` with ``share`` of the mass moved onto the ``scripted`` candidates, evenly:
    ``(1 - share) p + share u``, ``u`` uniform over them. Unchanged where none is scripted."""
    mask = np.asarray(scripted, dtype=bool)
    if share == 0 or not mask.any():
        return probabilities
    return (1.0 - share) * probabilities + share * mask / mask.sum()
