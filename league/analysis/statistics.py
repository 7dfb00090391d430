"""Intervals of measured rates: a Wilson score interval over games, a bootstrap interval over seeds.

Games of one pair on the fixed evaluation games are binomial (Wilson); the results of
several training seeds are few and not binomial, so their mean gets a percentile bootstrap.
"""

from __future__ import annotations

import math

import numpy as np

Z_95 = 1.959963984540054


def wilson_interval(wins: int, games: int, z: float = Z_95) -> tuple[float, float]:
    """95% Wilson score interval of a win rate."""
    if games == 0:
        return (0.0, 1.0)
    p = wins / games
    denom = 1 + z * z / games
    centre = (p + z * z / (2 * games)) / denom
    half = z * math.sqrt(p * (1 - p) / games + z * z / (4 * games * games)) / denom
    return (max(0.0, centre - half), min(1.0, centre + half))


BOOTSTRAP_SAMPLES = 10_000


def bootstrap_interval(values: list[float], seed: int = 0) -> tuple[float, float]:
    """95% percentile interval of the mean over resampled seeds."""
    rng = np.random.default_rng(seed)
    data = np.asarray(values)
    means = data[rng.integers(0, len(data), size=(BOOTSTRAP_SAMPLES, len(data)))].mean(axis=1)
    return float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))


def mean_interval(values: list[float], confidence: float = 0.95) -> tuple[float, float]:
    """Student-t interval of the mean of ``values`` (one per training seed): mean +- t * s / sqrt(n),
    ``t`` the two-sided quantile with ``n - 1`` degrees of freedom. Needs at least two values."""
    from scipy.stats import t  # here: seconds to import

    data = np.asarray(values, dtype=float)
    if len(data) < 2:
        raise ValueError(f"a Student-t interval needs at least 2 values, got {len(data)}")
    half = float(t.ppf(0.5 + confidence / 2, len(data) - 1) * data.std(ddof=1) / math.sqrt(len(data)))
    return float(data.mean()) - half, float(data.mean()) + half
