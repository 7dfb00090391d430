"""Seed-level statistics: the Student-t interval holds its coverage where the percentile
bootstrap did not; Welch's test, IQM and probability of improvement against hand computations."""

import math

import numpy as np
import pytest
from scipy.special import betainc

from league.analysis.statistics import SEED_INTERVAL, iqm, mean_interval, probability_of_improvement, welch_test, wilson_interval

STUDIES = 4000


def studies(rng: np.random.Generator, seeds: int) -> tuple[np.ndarray, np.ndarray]:
    """``STUDIES`` simulated studies of ``seeds`` normal seeds each, over several means and sds:
    (values (STUDIES, seeds), true mean per study)."""
    means = rng.choice([0.1, 0.5, 0.8, 3.0], size=STUDIES)
    sds = rng.choice([0.01, 0.05, 0.2, 1.0], size=STUDIES)
    return means[:, None] + sds[:, None] * rng.standard_normal((STUDIES, seeds)), means


def test_mean_interval_holds_the_true_mean_at_five_seeds():
    values, truth = studies(np.random.default_rng(20240601), seeds=5)
    intervals = np.array([mean_interval(v) for v in values])
    covered = np.mean((intervals[:, 0] <= truth) & (truth <= intervals[:, 1]))
    assert covered >= 0.93, covered  # nominal 0.95; 4000 studies: sd of the estimate 0.0034


def test_percentile_bootstrap_at_three_seeds_did_not():
    """Why ``mean_interval``: the percentile bootstrap over 3 seeds is [min, max] of the seeds,
    which holds the true mean with probability 1 - 2 (1/2)^3 = 0.75."""
    rng = np.random.default_rng(7)
    values, truth = studies(rng, seeds=3)
    resamples = rng.integers(0, 3, size=(STUDIES, 1000, 3))
    means = np.take_along_axis(values[:, None, :], resamples, axis=2).mean(axis=2)
    low, high = np.percentile(means, 2.5, axis=1), np.percentile(means, 97.5, axis=1)
    covered = np.mean((low <= truth) & (truth <= high))
    assert covered < 0.90, covered
    t_intervals = np.array([mean_interval(v) for v in values])
    assert np.mean((t_intervals[:, 0] <= truth) & (truth <= t_intervals[:, 1])) >= 0.93


def test_mean_interval_known_values():
    values = [0.2, 0.5, 0.8]
    s = math.sqrt(((0.2 - 0.5) ** 2 + 0 + (0.8 - 0.5) ** 2) / 2)  # sample sd: 0.3
    t = 0.95 / math.sqrt(2 * 0.975 * 0.025)  # t_{0.975, 2} = (2p - 1) / sqrt(2 p (1 - p)) at 2 df: 4.3027
    assert mean_interval(values) == pytest.approx((0.5 - t * s / math.sqrt(3), 0.5 + t * s / math.sqrt(3)), abs=1e-12)
    assert mean_interval([0.4, 0.4, 0.4]) == pytest.approx((0.4, 0.4))
    t90 = 0.90 / math.sqrt(2 * 0.95 * 0.05)  # t_{0.95, 2}: 2.9200
    assert mean_interval(values, confidence=0.90) == pytest.approx((0.5 - t90 * s / math.sqrt(3), 0.5 + t90 * s / math.sqrt(3)))
    assert SEED_INTERVAL == "Student-t 95% over seeds"


@pytest.mark.parametrize("values", [[0.5], []])
def test_mean_interval_needs_two_seeds(values):
    with pytest.raises(ValueError, match=f"at least 2 values.*got {len(values)}"):
        mean_interval(values)


def test_welch_test_hand_checked():
    # a: mean 2, var 1, n 3; b: mean 5, var 4, n 3 -> se^2 = 1/3 + 4/3 = 5/3, t = -3 / sqrt(5/3) = -2.3238
    # Welch-Satterthwaite df = (5/3)^2 / ((1/3)^2 / 2 + (4/3)^2 / 2) = 50/17 = 2.9412;
    # two-sided p = I_{df / (df + t^2)}(df / 2, 1 / 2) (the regularized incomplete beta) = 0.10448
    t, df = -3 / math.sqrt(5 / 3), 50 / 17
    p = betainc(df / 2, 0.5, df / (df + t * t))
    assert p == pytest.approx(0.10448, abs=5e-6)
    assert welch_test([1.0, 2.0, 3.0], [3.0, 5.0, 7.0]) == pytest.approx(p, rel=1e-9)
    # Student's pooled test (equal variances, 4 df) would give 0.0808: Welch's is not that
    assert welch_test([3.0, 5.0, 7.0], [1.0, 2.0, 3.0]) == pytest.approx(welch_test([1.0, 2.0, 3.0], [3.0, 5.0, 7.0]))


def test_welch_test_zero_variance_rule():
    assert welch_test([0.4, 0.4, 0.4], [0.4, 0.4]) == 1.0
    assert welch_test([0.4, 0.4, 0.4], [0.5, 0.5, 0.5]) == 0.0
    assert 0.0 < welch_test([0.4, 0.4, 0.4], [0.3, 0.5, 0.6]) < 1.0  # one group varies: the ordinary test
    with pytest.raises(ValueError, match="at least 2 values per group"):
        welch_test([0.4], [0.5, 0.6])


def test_iqm_hand_computed():
    assert iqm([1, 2, 3, 4, 5, 6, 7, 8]) == pytest.approx(4.5)  # the middle four: 3, 4, 5, 6
    assert iqm([0.0, 0.1, 0.2, 100.0]) == pytest.approx(0.15)  # the outlier and the lowest dropped
    assert iqm([8, 1, 7, 2, 6, 3, 5, 4]) == pytest.approx(4.5)  # order does not matter


def test_probability_of_improvement_hand_computed():
    # pairs (x, y): 3 > 1, 3 > 2, 1 = 1 (half), 1 < 2 -> (1 + 1 + 0.5 + 0) / 4
    assert probability_of_improvement([3.0, 1.0], [1.0, 2.0]) == pytest.approx(0.625)
    assert probability_of_improvement([1.0, 2.0], [3.0, 1.0]) == pytest.approx(0.375)
    assert probability_of_improvement([0.5, 0.5], [0.5]) == pytest.approx(0.5)
    assert probability_of_improvement([0.9, 0.8, 0.7], [0.1, 0.2]) == 1.0


def test_paired_t_test_hand_checked():
    from league.analysis.statistics import paired_t_test

    # d = (0.1, 0.2, 0.3): t = 0.2 / (0.1 / sqrt 3) = 3.4641 on 2 degrees of freedom; two-sided
    # p = 1 - t / sqrt(2 + t^2) = 0.07418 (the t distribution with 2 degrees of freedom in closed form).
    assert paired_t_test([0.1, 0.2, 0.3]) == pytest.approx(1 - 3.4641016 / math.sqrt(2 + 3.4641016**2), rel=1e-6)
    assert paired_t_test([0.0, 0.0, 0.0]) == 1.0 and paired_t_test([0.2, 0.2]) == 0.0
    with pytest.raises(ValueError):
        paired_t_test([0.1])


@pytest.mark.parametrize(
    "wins, games, low, high", [(0, 10, 0.0, 0.2775), (5, 10, 0.2366, 0.7634), (8, 10, 0.4902, 0.9433)]
)
def test_wilson_interval_known_values(wins, games, low, high):
    assert wilson_interval(wins, games) == pytest.approx((low, high), abs=1e-4)
