"""Intervals and comparisons of measured rates: over games of one pair, and over training seeds.

| what varies | how many | interval / test | why |
| --- | --- | --- | --- |
| the games of one attacker-team pair on the fixed starts | hundreds to thousands | ``wilson_interval`` | binomial counts; Wilson keeps its coverage near 0 and 1, where the normal approximation does not |
| one number per training seed (a win rate, an exploitability) | 3 to 10 | ``mean_interval`` (``SEED_INTERVAL``), ``welch_test`` | few values, not binomial: Student-t widens the interval for the sd estimated from n - 1 degrees of freedom |
| one number per training seed, robust summaries | any | ``iqm``, ``probability_of_improvement`` | rliable's (Agarwal et al., 2021) aggregates, in-house: rliable is archived |

No percentile bootstrap over seeds below about 20 seeds: at n = 3 its interval is within
[min, max] of the seeds and held the true mean in about 75% of simulated studies, not 95%
(``tests/analysis/test_statistics.py``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from envs.match import Z_95, wilson_interval  # noqa: F401  (its home: the scripted table prints it too)

SEED_INTERVAL = "Student-t 95% over seeds"  # printed beside every ``mean_interval`` on a results page


def mean_interval(values: Sequence[float], confidence: float = 0.95) -> tuple[float, float]:
    """Student-t interval of the mean over training seeds: mean +- t_{(1+c)/2, n-1} s / sqrt(n),
    with ``s`` the sample sd (n - 1 in the denominator). Needs at least 2 values."""
    from scipy import stats  # here, as in ``nash``: scipy.stats takes most of a second to import

    data = np.asarray(values, dtype=float)
    if data.size < 2:
        raise ValueError(f"mean_interval needs at least 2 values (one per seed), got {data.size}")
    mean = float(data.mean())
    half = float(stats.t.ppf((1 + confidence) / 2, data.size - 1) * data.std(ddof=1) / math.sqrt(data.size))
    return (mean - half, mean + half)


def welch_test(a: Sequence[float], b: Sequence[float]) -> float:
    """Two-sided p-value of Welch's t-test (unequal variances) of two groups of seeds.

    Each group needs at least 2 values. When both groups have zero variance the t statistic
    is undefined (scipy returns nan); then the p-value is 1.0 if the two means are equal and
    0.0 if they differ (every seed of one group above every seed of the other, without noise).
    """
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if x.size < 2 or y.size < 2:
        raise ValueError(f"welch_test needs at least 2 values per group, got {x.size} and {y.size}")
    if np.ptp(x) == 0 and np.ptp(y) == 0:  # every seed of each group equal (var() of equal floats can be 1e-33)
        return 1.0 if x[0] == y[0] else 0.0
    from scipy import stats

    return float(stats.ttest_ind(x, y, equal_var=False).pvalue)


def paired_t_test(differences: Sequence[float]) -> float:
    """Two-sided p-value of the paired t-test over seeds: are the per-seed differences (a
    trained player's rate minus its reference's, on that seed's games) centred on 0?

    Needs at least 2 values. With zero variance the p-value is 1.0 when every difference is
    0 and 0.0 otherwise (the same rule as ``welch_test``)."""
    d = np.asarray(differences, dtype=float)
    if d.size < 2:
        raise ValueError(f"paired_t_test needs at least 2 values (one per seed), got {d.size}")
    if np.ptp(d) == 0:
        return 1.0 if d[0] == 0 else 0.0
    from scipy import stats

    return float(stats.ttest_1samp(d, 0.0).pvalue)


def iqm(values: Sequence[float]) -> float:
    """Interquartile mean (rliable's): the mean of the middle 50% of the values."""
    from scipy import stats

    return float(stats.trim_mean(np.asarray(values, dtype=float), 0.25))


def probability_of_improvement(a: Sequence[float], b: Sequence[float]) -> float:
    """P(X > Y) + 0.5 P(X = Y) for X a seed of ``a`` and Y a seed of ``b``, over all pairs
    (rliable's probability of improvement, the Mann-Whitney U statistic over len(a) len(b))."""
    x, y = np.asarray(a, dtype=float)[:, None], np.asarray(b, dtype=float)[None, :]
    return float(np.mean((x > y) + 0.5 * (x == y)))

