"""Statistics on hand-worked examples (reports/stats.py). Runtime: < 1 s."""
from __future__ import annotations

import numpy as np
import pytest

from reports.stats import (
    bootstrap_band,
    bootstrap_ci,
    bootstrap_contrast_ci,
    convergence_test,
    iqm,
    mann_whitney_greater,
    percentile_curve,
    quantile_curve,
    slope_ci,
    smooth,
    smoothing_window,
)


def test_bootstrap_ci__of_a_constant_is_that_constant():
    assert bootstrap_ci([2.5] * 7) == (2.5, 2.5)


def test_bootstrap_ci__of_one_value_and_of_nothing():
    assert bootstrap_ci([4.0]) == (4.0, 4.0)
    lo, hi = bootstrap_ci([])
    assert np.isnan(lo) and np.isnan(hi)


def test_bootstrap_ci__brackets_the_mean_and_lies_within_the_data():
    x = np.array([0.0, 1.0, 2.0, 3.0, 10.0])
    lo, hi = bootstrap_ci(x, seed=3)
    assert 0.0 <= lo < x.mean() < hi <= 10.0
    assert bootstrap_ci(x, seed=3) == (lo, hi)  # seeded: same interval every time


def test_bootstrap_ci__two_values_spans_them():
    # Resampled means of {0, 1} with n = 2 are 0, 0.5, 1 w.p. 1/4, 1/2, 1/4: the 2.5% and
    # 97.5% quantiles of 2000 resamples are 0 and 1.
    assert bootstrap_ci([0.0, 1.0]) == (0.0, 1.0)


def test_bootstrap_ci__ignores_nans():
    assert bootstrap_ci([1.0, np.nan, 1.0]) == (1.0, 1.0)


def test_bootstrap_contrast_ci__difference_of_constants_is_exact():
    est, lo, hi = bootstrap_contrast_ci([[3.0, 3.0], [1.0, 1.0, 1.0]], [1, -1])
    assert (est, lo, hi) == (2.0, 2.0, 2.0)
    est, lo, hi = bootstrap_contrast_ci([[5.0], [1.0], [2.0], [1.0]], [1, -1, -1, 1])
    assert est == lo == hi == 3.0  # (5 - 1) - (2 - 1)


def test_bootstrap_contrast_ci__empty_sample_gives_nan():
    assert all(np.isnan(v) for v in bootstrap_contrast_ci([[1.0], []], [1, -1]))


def test_bootstrap_band__one_run_collapses_and_identical_runs_have_no_width():
    c = np.array([[1.0, 2.0, 3.0]])
    mean, lo, hi = bootstrap_band(c)
    np.testing.assert_array_equal(mean, c[0])
    np.testing.assert_array_equal(lo, c[0])
    mean, lo, hi = bootstrap_band(np.tile([1.0, 5.0], (4, 1)))
    np.testing.assert_array_equal(lo, [1.0, 5.0])
    np.testing.assert_array_equal(hi, [1.0, 5.0])


def test_bootstrap_band__two_runs_band_spans_them():
    mean, lo, hi = bootstrap_band(np.array([[0.0, 0.0], [2.0, 4.0]]))
    np.testing.assert_array_equal(mean, [1.0, 2.0])
    np.testing.assert_array_equal(lo, [0.0, 0.0])
    np.testing.assert_array_equal(hi, [2.0, 4.0])


def test_iqm__worked_by_hand():
    # sorted: 1 2 3 4 6 7 8 100; drop 2 from each end -> 3 4 6 7 -> 20 / 4 = 5
    assert iqm([1, 2, 3, 4, 100, 6, 7, 8]) == 5.0
    # n = 5: int(0.25 * 5) = 1 dropped from each end -> 2 3 4 -> 3
    assert iqm([5, 1, 4, 2, 3]) == 3.0
    assert np.isnan(iqm([]))


def test_percentile_curve__tiny_array():
    pct, val = percentile_curve([0.3, 0.1, 0.2, 0.4])
    np.testing.assert_allclose(pct, [12.5, 37.5, 62.5, 87.5])
    np.testing.assert_allclose(val, [0.1, 0.2, 0.3, 0.4])


def test_quantile_curve__interpolates_between_plotting_positions():
    x = [0.3, 0.1, 0.2, 0.4]
    q = quantile_curve(x, np.array([0.0, 12.5, 25.0, 50.0, 87.5, 100.0]))
    # flat beyond the ends, exact at the Hazen positions, linear in between
    np.testing.assert_allclose(q, [0.1, 0.1, 0.15, 0.25, 0.4, 0.4])


def test_smooth__trailing_mean():
    np.testing.assert_allclose(smooth([1, 2, 3, 4], 2), [1.0, 1.5, 2.5, 3.5])
    np.testing.assert_allclose(smooth([1, 2, 3], 1), [1, 2, 3])
    assert smoothing_window(2000) == 100 and smoothing_window(10) == 1 and smoothing_window(200) == 10


def test_mann_whitney_greater__direction_and_degenerate_cases():
    a, b = np.arange(10, 20), np.arange(0, 10)
    assert mann_whitney_greater(a, b) < 0.001
    assert mann_whitney_greater(b, a) > 0.99
    assert np.isnan(mann_whitney_greater([1, 1], [1, 1]))
    assert np.isnan(mann_whitney_greater([], [1]))


def test_slope_ci__straight_line_is_exact():
    s, lo, hi = slope_ci(2.0 * np.arange(10) + 1.0)
    assert s == pytest.approx(2.0) and lo == pytest.approx(2.0) and hi == pytest.approx(2.0)
    assert np.isnan(slope_ci([1.0, 2.0])[0])


def test_convergence_test__rise_then_plateau_converges():
    rng = np.random.default_rng(0)
    t = np.arange(500)
    y = 10 * (1 - np.exp(-t / 60)) + rng.normal(0, 0.5, t.size)
    r = convergence_test(y)
    assert r is not None and r.converged and r.window == 100
    # first window mean = 10 (1 - 0.6 (1 - e^(-5/3))) = 5.1, last = 10: gain about 4.9
    assert 4.5 < r.gain < 5.3


def test_convergence_test__still_rising_fails_and_flat_fails():
    rng = np.random.default_rng(1)
    t = np.arange(500)
    rising = convergence_test(10 * (t / 500) ** 2 + rng.normal(0, 0.5, t.size))
    # gain = 10 (0.81 - 0.01) = 8; drift over the last window = 10 (1 - 0.64) = 3.6 > 20% of 8
    assert rising is not None and not rising.converged and rising.drift_lo > rising.tolerance
    flat = convergence_test(rng.normal(0, 0.5, t.size))
    assert flat is not None and not flat.converged  # no gain


def test_convergence_test__too_short_is_none():
    assert convergence_test(np.arange(40.0)) is None  # windows of 8 < 10 episodes
