"""Statistics on hand-worked examples and by simulation (reports/stats.py). Runtime: ~2 s.

Closed forms used for Student t with 2 degrees of freedom (no table needed):
cdf(t) = 1/2 + t / (2 sqrt(2 + t^2)) and the quantile t_p = (2p - 1) / sqrt(2 p (1 - p)).
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import stats as sps

from reports.stats import (
    Convergence,
    CurveShape,
    TTest,
    bootstrap_ci,
    contrast_t,
    convergence_test,
    curve_shape,
    iqm,
    mean_ci,
    percentile_curve,
    probability_of_improvement,
    quantile_curve,
    simultaneous_band,
    smooth,
    smoothing_window,
    t_band,
    t_interval,
    t_test,
    welch_parts,
    zero_events_bound,
)


def t2_sf(t: float) -> float:
    return 0.5 - t / (2.0 * np.sqrt(2.0 + t * t))


def t2_ppf(p: float) -> float:
    return (2 * p - 1) / np.sqrt(2 * p * (1 - p))


# ---------------------------------------------------------------- t tests
def test_t_test__one_sample_worked_by_hand():
    # x = 1, 2, 3: mean 2, s = 1, se = 1/sqrt(3), df = 2, t = 2 sqrt(3)
    t = t_test([[1.0, 2.0, 3.0]], [1.0])
    se = 1 / np.sqrt(3)
    assert t.estimate == pytest.approx(2.0) and t.se == pytest.approx(se) and t.df == pytest.approx(2.0)
    half = t2_ppf(0.975) * se  # 4.3027 x 0.5774
    assert (t.lo, t.hi) == (pytest.approx(2 - half), pytest.approx(2 + half))
    assert t.p_greater == pytest.approx(t2_sf(2 * np.sqrt(3)))  # 0.0371
    assert t.p_less == pytest.approx(1 - t2_sf(2 * np.sqrt(3)))
    assert t.valid


def test_t_test__null_is_subtracted_from_the_estimate_not_the_interval():
    t = t_test([[1.0, 2.0, 3.0]], [1.0], null=2.0)
    assert t.estimate == pytest.approx(0.0)
    assert t.p_greater == pytest.approx(0.5) and t.p_less == pytest.approx(0.5)
    assert t.lo < 2.0 < t.hi  # CI of the mean itself


def test_t_test__level_sets_the_interval_width():
    t = t_test([[1.0, 2.0, 3.0]], [1.0], level=0.9)
    half = t2_ppf(0.95) / np.sqrt(3)  # 2.92 / sqrt(3)
    assert (t.lo, t.hi) == (pytest.approx(2 - half), pytest.approx(2 + half))


def test_t_test__weights_scale_estimate_and_error():
    t = t_test([[1.0, 2.0, 3.0]], [2.0])  # 2 x mean, 2 x se, the same t
    assert (t.estimate, t.se, t.df) == (pytest.approx(4.0), pytest.approx(2 / np.sqrt(3)), pytest.approx(2.0))
    assert t.p_greater == pytest.approx(t2_sf(2 * np.sqrt(3)))


def test_t_test__welch_two_samples_worked_by_hand():
    # means 2 and 6, variances 1 and 4, n = 3: c = 1/3, 4/3; se^2 = 5/3;
    # df = (5/3)^2 / ((1/9 + 16/9) / 2) = 50/17
    t = t_test([[1.0, 2.0, 3.0], [4.0, 6.0, 8.0]], [1.0, -1.0])
    assert t.estimate == pytest.approx(-4.0)
    assert t.se == pytest.approx(np.sqrt(5 / 3))
    assert t.df == pytest.approx(50 / 17)
    assert t.p_less < 0.05 < t.p_greater
    assert t.p_less + t.p_greater == pytest.approx(1.0)


def test_t_test__contrast_of_four_means():
    # (5 - 1) - (2 - 1) = 3, every variance 2 and n = 2: c = 1 each, se^2 = 4
    t = t_test([[4.0, 6.0], [0.0, 2.0], [1.0, 3.0], [0.0, 2.0]], [1, -1, -1, 1])
    assert t.estimate == pytest.approx(3.0) and t.se == pytest.approx(2.0)
    assert t.df == pytest.approx(4.0)  # (4 c)^2 / (4 c^2 / 1)


def test_t_test__no_variance_is_decided_exactly_and_too_few_values_give_nan():
    t = t_test([[2.0, 2.0, 2.0]], [1.0])
    assert (t.estimate, t.lo, t.hi, t.p_greater, t.p_less) == (2.0, 2.0, 2.0, 0.0, 1.0)
    assert t.se == 0.0 and np.isinf(t.df) and t.valid
    t = t_test([[2.0, 2.0, 2.0]], [1.0], null=3.0)
    assert (t.p_greater, t.p_less) == (1.0, 0.0)
    t = t_test([[2.0, 2.0, 2.0]], [1.0], null=2.0)
    assert (t.p_greater, t.p_less) == (1.0, 1.0)  # exactly at the null: no evidence either way
    assert not t_test([[1.0], [1.0, 2.0]], [1, -1]).valid
    assert not t_test([], []).valid
    assert not t_test([[1.0, np.nan], [1.0, 2.0]], [1, -1]).valid  # NaNs are dropped first
    with pytest.raises(ValueError, match="^samples and weights must have the same length$"):
        t_test([[1.0, 2.0]], [1.0, -1.0])
    t = t_test([[0.5, 0.5, 0.5]], [1.0])  # exact and positive, however small
    assert (t.p_greater, t.p_less) == (0.0, 1.0)


@pytest.mark.parametrize("weights", [[1.0], [-1.0], [1.0, -1.0], [1.0, -1.0, -1.0, 1.0], [-1.5, 0.5, 1.0]])
def test_contrast_t__vectorized_is_the_one_test_per_row(weights):
    """The calibration's vectorized test (one row per simulation) gives each row what
    ``t_test`` gives it alone, field by field, exact rows included."""
    rng = np.random.default_rng(3)
    groups = [rng.normal(size=(40, 3 + k)) * (k + 1) for k in range(len(weights))]
    for g in groups:
        g[0] = 1.0  # a variance-free row: decided exactly
    t = contrast_t(groups, weights, 0.25, axis=1)
    for m in range(40):
        one = t_test([g[m] for g in groups], weights, 0.25)
        got = [float(getattr(t, f)[m]) for f in ("estimate", "se", "df", "lo", "hi", "p_greater", "p_less")]
        np.testing.assert_allclose(got, list(one.__dict__.values()), rtol=1e-12)
    t0 = contrast_t(groups, weights, 0.0, axis=1)  # the CI is the contrast's: the null moves only the test
    np.testing.assert_allclose(t.lo, t0.lo, rtol=1e-12)
    np.testing.assert_allclose(t.hi, t0.hi, rtol=1e-12)


def test_contrast_t__three_or_more_means_take_the_welch_satterthwaite_df():
    # slope-like contrast (-1, 0, 1), variances 1, 4, 9 at n = 3: c = 1/3, 0, 3
    g = [np.array([0.0, 1.0, 2.0]), np.array([0.0, 2.0, 4.0]), np.array([3.0, 6.0, 9.0])]
    t = contrast_t(g, [-1.0, 0.0, 1.0])
    var = 1 / 3 + 3.0
    assert float(t.estimate) == pytest.approx(5.0) and float(t.se) == pytest.approx(np.sqrt(var))
    assert float(t.df) == pytest.approx(var ** 2 / ((1 / 3) ** 2 / 2 + 9.0 / 2))
    q = sps.t.ppf(0.975, float(t.df))
    assert (float(t.lo), float(t.hi)) == (pytest.approx(5 - q * np.sqrt(var)), pytest.approx(5 + q * np.sqrt(var)))


def test_t_interval__is_scipys_t_interval_along_an_axis_and_omits_nans():
    x = np.array([[1.0, 2.0, 3.0], [2.0, 2.0, np.nan]])
    lo, hi = t_interval(x, axis=1)
    half = t2_ppf(0.975) / np.sqrt(3)
    np.testing.assert_allclose([lo[0], hi[0]], [2 - half, 2 + half])
    assert np.isnan(lo[1]) and np.isnan(hi[1])
    lo, hi = t_interval(x.T, axis=0, omit_nan=True)
    assert lo[1] == hi[1] == 2.0  # two equal values: no width


def test_welch_parts__vectorized_over_columns():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a column without variance is not a numerical accident
        est, se, df = welch_parts(np.array([[1.0, 2.0], [0.0, 0.0]]), np.array([[1.0, 0.0], [1.0, 0.0]]),
                                  np.array([3, 3]), np.array([1.0, -1.0]))
    np.testing.assert_allclose(est, [1.0, 2.0])
    np.testing.assert_allclose(se, [np.sqrt(2 / 3), 0.0])
    assert df[0] == pytest.approx(4.0) and np.isinf(df[1])
    with pytest.raises(ValueError):  # one weight per sample
        welch_parts(np.zeros(2), np.ones(2), np.array([3, 3, 3]), np.ones(2))
    with pytest.raises(ValueError):
        welch_parts(np.zeros(2), np.ones(2), np.array([3, 3]), np.ones(3))


def test_mean_ci__is_the_t_interval_and_handles_small_samples():
    m, lo, hi = mean_ci([1.0, 2.0, 3.0])
    half = t2_ppf(0.975) / np.sqrt(3)
    assert (m, lo, hi) == (2.0, pytest.approx(2 - half), pytest.approx(2 + half))
    assert lo < hi
    m, lo, hi = mean_ci([1.0, 2.0, 3.0], level=0.9)
    assert lo == pytest.approx(2 - t2_ppf(0.95) / np.sqrt(3))
    m, lo, hi = mean_ci([4.0])
    assert m == 4.0 and np.isnan(lo) and np.isnan(hi)
    assert all(np.isnan(mean_ci([])))
    assert mean_ci([1.0, np.nan, 3.0])[0] == 2.0


def test_simultaneous_band__bonferroni_over_points_worked_by_hand():
    a = np.array([[1.0, 10.0], [2.0, 11.0], [3.0, 12.0]])
    b = np.array([[0.0, 9.0], [1.0, 10.0], [2.0, 11.0]])
    diff, lo, hi = simultaneous_band(a, b)
    # every column: difference 1, variances 1 and 1, n = 3 -> se sqrt(2/3), df 4;
    # one-sided level 0.05 / 2 points -> t_{0.975, 4} = 2.776445
    half = 2.7764451051977987 * np.sqrt(2 / 3)
    np.testing.assert_allclose(diff, [1.0, 1.0])
    np.testing.assert_allclose(lo, [1 - half, 1 - half])
    np.testing.assert_allclose(hi, [1 + half, 1 + half])
    for bad in ((a[:1], b), (a, b[:1]), (a[:, 0], b), (a, b[:, 0]), (a, b[:, :1])):
        with pytest.raises(ValueError, match="equal G"):
            simultaneous_band(*bad)
    # a column without variance is exact (df infinite); alpha sets the width
    _, lo, _ = simultaneous_band(np.array([[1.0, 2.0], [1.0, 3.0]]), np.array([[0.0, 0.0], [0.0, 1.0]]))
    assert lo[0] == 1.0
    _, lo01, _ = simultaneous_band(a, b, alpha=0.1)
    np.testing.assert_allclose(lo01, 1 - 2.1318467813362907 * np.sqrt(2 / 3))  # t_{0.95, 4}


def test_zero_events_bound__exact_and_near_rule_of_three():
    assert zero_events_bound(3) == pytest.approx(1 - 0.05 ** (1 / 3))  # 0.6316
    assert zero_events_bound(300) == pytest.approx(3 / 300, rel=0.01)
    assert zero_events_bound(1) == pytest.approx(0.95)
    assert zero_events_bound(1, alpha=0.1) == pytest.approx(0.9)
    assert np.isnan(zero_events_bound(0))


# ----------------------------------------------------------------- rliable
def test_iqm__worked_by_hand():
    # sorted: 1 2 3 4 6 7 8 100; drop 2 from each end -> 3 4 6 7 -> 20 / 4 = 5
    assert iqm([1, 2, 3, 4, 100, 6, 7, 8]) == 5.0
    assert iqm([5, 1, 4, 2, 3]) == 3.0  # one dropped from each end
    assert iqm([7.0]) == 7.0
    assert np.isnan(iqm([]))


def test_probability_of_improvement__worked_by_hand():
    assert probability_of_improvement([3.0, 4.0], [1.0, 2.0]) == 1.0
    assert probability_of_improvement([1.0, 2.0], [2.0, 3.0]) == 0.125  # one tie of four pairs
    assert probability_of_improvement([2.0], [2.0]) == 0.5
    assert np.isnan(probability_of_improvement([], [1.0]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # decided here, not by a warning deep in scipy
        assert np.isnan(probability_of_improvement([1.0], [np.nan]))
        assert np.isnan(probability_of_improvement([], []))


# ---------------------------------------------------------------- bootstrap
def test_bootstrap_ci__constants_single_values_and_nans():
    assert bootstrap_ci([2.5] * 7) == (2.5, 2.5)
    assert bootstrap_ci([4.0]) == (4.0, 4.0)
    assert bootstrap_ci([1.0, np.nan, 1.0]) == (1.0, 1.0)
    assert all(np.isnan(bootstrap_ci([])))


def test_bootstrap_ci__two_values_quantiles_worked_by_hand():
    # Resampled means of {0, 1} are 0, 0.5, 1 w.p. 1/4, 1/2, 1/4: the 2.5/97.5% quantiles
    # are 0 and 1; at level 0.2 the 40/60% quantiles are both 0.5.
    assert bootstrap_ci([0.0, 1.0]) == (0.0, 1.0)
    assert bootstrap_ci([0.0, 1.0], level=0.2) == (0.5, 0.5)
    assert bootstrap_ci([0.0, 1.0], level=0.4) == (0.5, 0.5)  # 30/70% quantiles
    assert bootstrap_ci([0.0, 1.0], level=0.6) == (0.0, 1.0)  # 20/80% quantiles
    assert bootstrap_ci([0.0, 1.0], statistic=lambda m: m.max(axis=-1), level=0.2) == (1.0, 1.0)


def test_bootstrap_ci__is_seeded():
    x = np.array([0.0, 1.0, 2.0, 3.0, 10.0])
    lo, hi = bootstrap_ci(x, seed=3)
    assert 0.0 <= lo < x.mean() < hi <= 10.0
    assert bootstrap_ci(x, seed=3) == (lo, hi)
    assert bootstrap_ci(x, seed=4) != (lo, hi)
    assert bootstrap_ci(x, n_boot=50, seed=3) != (lo, hi)
    assert bootstrap_ci(x) == bootstrap_ci(x, n_boot=2000, level=0.95, seed=0)  # the defaults


def test_t_band__is_the_t_interval_per_point_and_ignores_nans():
    c = np.array([[0.0, 1.0, np.nan], [2.0, 1.0, 5.0], [4.0, 4.0, np.nan]])
    mean, lo, hi = t_band(c)
    for j in range(2):
        m, a, b = mean_ci(c[:, j])
        assert (mean[j], lo[j], hi[j]) == pytest.approx((m, a, b))
    assert mean[2] == 5.0 and np.isnan(lo[2]) and np.isnan(hi[2])  # one value: no band
    assert hi[0] - mean[0] == pytest.approx(sps.t.ppf(0.975, 2) * 2.0 / np.sqrt(3))
    _, lo90, hi90 = t_band(c, level=0.9)
    assert lo[0] < lo90[0] < mean[0] < hi90[0] < hi[0]
    np.testing.assert_array_equal(t_band(c[:1])[1], [np.nan] * 3)  # one seed: no band
    for bad in (np.zeros((0, 3)), np.zeros(3)):
        with pytest.raises(ValueError, match=r"\(S, T\)"):
            t_band(bad)


# ------------------------------------------------------------------ curves
def test_percentile_and_quantile_curves__tiny_array():
    pct, val = percentile_curve([0.3, 0.1, 0.2, 0.4])
    np.testing.assert_allclose(pct, [12.5, 37.5, 62.5, 87.5])
    np.testing.assert_allclose(val, [0.1, 0.2, 0.3, 0.4])
    q = quantile_curve([0.3, 0.1, 0.2, 0.4], np.array([0.0, 12.5, 25.0, 50.0, 87.5, 100.0]))
    np.testing.assert_allclose(q, [0.1, 0.1, 0.15, 0.25, 0.4, 0.4])
    empty = quantile_curve([], np.array([50.0, 60.0]))
    assert empty.shape == (2,) and np.isnan(empty).all()
    np.testing.assert_allclose(quantile_curve([0.0, 1.0], [50, 75]), [0.5, 1.0])  # integer percentiles
    pct, val = percentile_curve([np.nan])
    assert pct.size == 0 and val.size == 0
    assert percentile_curve([3, 1, 2])[1].dtype == np.float64  # integers become floats


def test_smooth__trailing_mean():
    np.testing.assert_allclose(smooth([1, 2, 3, 4], 2), [1.0, 1.5, 2.5, 3.5])
    np.testing.assert_allclose(smooth([1, 2, 3], 1), [1, 2, 3])
    np.testing.assert_allclose(smooth([1, 2, 3], 0), [1, 2, 3])  # window at least 1
    np.testing.assert_allclose(smooth([1, 3], 5), [1.0, 2.0])
    assert smooth([], 3).size == 0
    np.testing.assert_allclose(smooth(np.array([[1.0], [3.0]]), 2), [1.0, 2.0])  # a column is a curve
    # A missing episode leaves a gap of one window, not the rest of the curve.
    np.testing.assert_allclose(smooth(np.array([1.0, 2.0, np.nan, 4, 5, 6]), 2), [1.0, 1.5, 2.0, 4.0, 4.5, 5.5])
    assert np.isnan(smooth(np.array([1.0, np.nan, np.nan, 4.0]), 2)[2])
    assert smoothing_window(2000) == 100 and smoothing_window(10) == 1 and smoothing_window(200) == 10
    assert smoothing_window(5000) == 100  # capped


# ------------------------------------------------------------- convergence
def test_curve_shape__reads_the_first_and_last_windows():
    # T = 50, frac 0.2 -> windows of 10: first all 0, middle 7, last 10..19 (mean 14.5, slope 1)
    y = np.r_[np.zeros(10), np.full(30, 7.0), 10.0 + np.arange(10.0)]
    s = curve_shape(y)
    assert s == CurveShape(gain=14.5, drift=10.0, window=10)
    s = curve_shape(np.r_[np.full(10, 3.0), np.zeros(30), np.full(10, 1.0)])
    assert (s.gain, s.drift) == (pytest.approx(-2.0), pytest.approx(0.0))
    assert curve_shape(np.arange(45.0)) is None  # windows of 9 < 10
    assert curve_shape(np.arange(50.0)).window == 10
    assert curve_shape(np.arange(50.0), frac=0.4).window == 20
    assert curve_shape(np.arange(45.0), min_window=9).window == 9
    assert curve_shape(np.arange(10.0), min_window=2) == CurveShape(8.0, 2.0, 2)  # [8, 9] - [0, 1]
    assert curve_shape(np.arange(5.0), min_window=1) is None  # one episode has no slope


def test_convergence_test__worked_by_hand():
    # gains 4 5 6, drifts 0 0.1 -0.1, tol 0.2: d - 0.2 g = -0.8 -0.9 -1.3 (mean -1, se 0.1528),
    # d + 0.2 g = 0.8 1.1 1.1 (mean 1, se 0.1): every part significant at 0.05 with df 2.
    shapes = [CurveShape(g, d, 40) for g, d in zip((4.0, 5.0, 6.0), (0.0, 0.1, -0.1), strict=True)]
    r = convergence_test(shapes, rel_tol=0.2)
    assert r.window == 40 and r.rel_tol == 0.2
    assert r.gain.estimate == pytest.approx(5.0)
    assert r.above.estimate == pytest.approx(-1.0)
    assert r.above.p_less == pytest.approx(1 - t2_sf(-1.0 / np.sqrt(0.07 / 3)))
    assert r.below.estimate == pytest.approx(1.0) and r.below.se == pytest.approx(0.1)
    assert r.below.p_greater == pytest.approx(t2_sf(10.0))
    assert r.supported() and not r.contradicted()
    # still rising: drifts 2 2.2 1.8 -> d - 0.2 g = 1.2 1.2 0.6 (mean 1, se 0.2, t = 5)
    rising = convergence_test([CurveShape(g, d, 40) for g, d in
                               zip((4.0, 5.0, 6.0), (2.0, 2.2, 1.8), strict=True)])
    assert rising.above.p_greater == pytest.approx(t2_sf(5.0))
    assert rising.contradicted() and not rising.supported()
    # collapsing: drifts -2 -2.2 -1.8 -> d + 0.2 g = -1.2 -1.2 -0.6
    falling = convergence_test([CurveShape(g, -d, 40) for g, d in
                                zip((4.0, 5.0, 6.0), (2.0, 2.2, 1.8), strict=True)])
    assert falling.below.p_less == pytest.approx(t2_sf(5.0))
    assert falling.contradicted() and not falling.supported()
    # a loss of reward is contradicted even with a flat end
    lost = convergence_test([CurveShape(-g, 0.0, 40) for g in (4.0, 5.0, 6.0)])
    assert lost.contradicted() and not lost.supported()
    # alpha is honoured: p(gain) = 0.0066 passes at 0.05 and fails at 0.001
    assert not r.supported(alpha=0.001)
    assert not rising.contradicted(alpha=0.001)  # p = 0.0189
    assert convergence_test([]).window == 0
    assert convergence_test([CurveShape(1.0, 0.0, 40), CurveShape(2.0, 0.0, 30)]).window == 30


# -------------------------------------------------------------- simulation
def test_t_test__rate_under_the_null_and_power_by_simulation():
    # 3 vs 3 seeds, unequal variances: one-sided rejection rate at 0.05 under the null,
    # +- 2 MC s.e. (1000 sims: 0.0138); power at a difference of 3 seed s.d. is high.
    rng = np.random.default_rng(0)
    sims = 1000
    null = sum(t_test([rng.normal(0, 1, 3), rng.normal(0, 2, 3)], [1, -1]).p_greater < 0.05
               for _ in range(sims)) / sims
    power = sum(t_test([rng.normal(3, 1, 3), rng.normal(0, 1, 3)], [1, -1]).p_greater < 0.05
                for _ in range(sims)) / sims
    assert null <= 0.05 + 0.0138
    assert null > 0.02  # not vacuous either
    assert power > 0.6


def test_mean_ci__covers_the_mean_95_percent_at_three_seeds():
    rng = np.random.default_rng(1)
    hits = 0
    for _ in range(1000):
        _, lo, hi = mean_ci(rng.normal(1.0, 2.0, 3))
        hits += lo <= 1.0 <= hi
    assert abs(hits / 1000 - 0.95) < 0.02


def _p(greater: float, less: float) -> TTest:
    return TTest(0.0, 1.0, 2.0, -1.0, 1.0, greater, less)


def _support(p_gain: float, p_not_rising: float, p_not_falling: float) -> Convergence:
    return Convergence(_p(p_gain, 1.0), _p(1.0, p_not_rising), _p(p_not_falling, 1.0), 0.2, 40)


def _contra(p_loss: float, p_rising: float, p_falling: float) -> Convergence:
    return Convergence(_p(1.0, p_loss), _p(p_rising, 1.0), _p(1.0, p_falling), 0.2, 40)


def test_convergence__significance_is_strictly_below_alpha():
    # each part exactly at alpha (the others well below, or absent) is not significant
    at = 0.05
    for k in range(3):
        sup = _support(*(at if i == k else 0.001 for i in range(3)))
        assert not sup.supported(alpha=at) and sup.supported(alpha=at + 1e-9), k
        con = _contra(*(at if i == k else 1.0 for i in range(3)))
        assert not con.contradicted(alpha=at) and con.contradicted(alpha=at + 1e-9), k


def test_metric_estimate__a_seed_interval_stays_inside_the_metrics_range() -> None:
    """Three seeds with success 0.0, 0.1, 0.9: the t interval would reach below 0; the
    reported one (logit scale) lies inside [0, 1] without cutting, and a count's (log
    scale) above 0; the mean is untouched. A return is unbounded: the plain t interval."""
    import pandas as pd

    from reports.tables.summary import metric_estimate

    rows = pd.DataFrame({"cell_id": ["a", "b", "c"], "success_rate": [0.0, 0.1, 0.9],
                         "team_return": [0.0, 0.1, 0.9], "mean_candidates": [0.5, 0.1, 0.9]})
    mean, lo, hi, unit = metric_estimate(rows, "success_rate")
    assert unit == "seeds" and mean == pytest.approx(1 / 3)
    assert 0.0 < lo < mean < hi < 1.0
    _, lo_r, hi_r, _ = metric_estimate(rows, "team_return")
    assert lo_r < -0.5 and hi_r > 1.0
    _, lo_c, hi_c, _ = metric_estimate(rows, "mean_candidates")
    assert 0.0 < lo_c < 0.5 < hi_c


def test_metric_estimate__two_seeds_use_the_t_interval_one_seed_its_episodes() -> None:
    """Two seeds are enough for the seed interval (Cox's: a payload is never negative,
    by construction); one seed falls back to a bootstrap over its episodes, inside their range."""
    import pandas as pd

    from reports.tables.summary import metric_estimate

    two = pd.DataFrame({"cell_id": ["a", "b"], "payload_scalars_per_step": [0.0, 10.0],
                        "predictor_error": [0.0, 10.0]})
    for metric in ("payload_scalars_per_step", "predictor_error"):
        mean, lo, hi, unit = metric_estimate(two, metric)
        assert (mean, unit) == (5.0, "seeds") and 0.0 <= lo < 1e-6 and hi > 10.0
    one = pd.DataFrame({"cell_id": ["a"] * 4, "success_rate": [0.0, 1.0, 1.0, float("nan")]})
    mean, lo, hi, unit = metric_estimate(one, "success_rate")
    assert unit == "episodes" and mean == pytest.approx(2 / 3) and 0.0 <= lo <= mean <= hi <= 1.0


def test_metric_estimate__no_finite_value_gives_nan_and_the_bootstrap_is_seeded() -> None:
    import math

    import pandas as pd

    from reports.tables.summary import metric_estimate

    empty = pd.DataFrame({"cell_id": ["a", "a"], "success_rate": [float("nan")] * 2})
    got = metric_estimate(empty, "success_rate")
    assert all(math.isnan(v) for v in got[:3]) and got[3] == "-"
    single = pd.DataFrame({"cell_id": ["a"] * 2, "success_rate": [0.5, float("nan")]})
    assert metric_estimate(single, "success_rate")[:3] == (0.5, 0.5, 0.5)  # one finite value
    one = pd.DataFrame({"cell_id": ["a"] * 40, "success_rate": np.random.default_rng(3).random(40)})
    assert metric_estimate(one, "success_rate") == metric_estimate(one, "success_rate")


# ------------------------------------------------------ intervals with a range
def test_rate_ci__inside_0_1_by_construction_and_covers_at_3_seeds():
    from reports.stats import coverage, positive_ci, rate_ci, uninformative

    m, lo, hi = rate_ci([0.0, 0.6, 1.0])  # a t interval would be [-0.67, 1.7]
    assert m == pytest.approx(1.6 / 3) and 0.0 <= lo < m < hi <= 1.0
    assert uninformative(lo, hi)
    m, lo, hi = rate_ci([0.02, 0.03, 0.025])
    assert 0.0 < lo < 0.025 < hi < 0.06 and not uninformative(lo, hi)
    assert rate_ci([0.4, 0.4, 0.4]) == (pytest.approx(0.4), pytest.approx(0.4), pytest.approx(0.4))
    assert np.isnan(rate_ci([0.5])[1]) and np.isnan(rate_ci([])[0])
    m, lo, hi = positive_ci([1.0, 20.0, 60.0])  # a t interval would reach below 0
    assert 0.0 < lo < m < hi
    # simulated coverage at 3 seeds and a wide spread: the logit t interval reaches 93%,
    # the plain t interval does not (the reason for the change)
    assert coverage("rate", 0.6, 0.35, 3, sims=2000) >= 0.93
    assert coverage("positive", 16.0, 12.0, 3, sims=2000) >= 0.93
    rng = np.random.default_rng(1)
    k = 0.6 * 0.4 / 0.35**2 - 1
    x = rng.beta(0.6 * k, 0.4 * k, (2000, 3))
    hits = [lo <= 0.6 <= hi for lo, hi in (mean_ci(r)[1:] for r in x)]
    assert np.mean(hits) < 0.92


def test_rate_ci__holds_the_mean_printed_beside_it():
    """A skewed sample puts the logit interval's centre off the plain mean: tuned-n40's
    decentralized seeds printed 100.0% [99.8%, 99.9%] (decision 0248). The interval
    extends to the mean, and no further (widening cannot lower its coverage)."""
    from scipy.special import expit, logit

    from reports.stats import rate_ci

    seeds = [0.998, 1.0, 1.0, 1.0, 1.0]  # tuned-n40, decentralized, argmax
    m, lo, hi = rate_ci(seeds)
    assert m == pytest.approx(0.9996) and lo < 0.999 and hi == m  # the logit interval ended at 0.9995
    x = [0.2, 0.3, 0.25]  # where the logit interval holds the mean, it is that interval
    ci = sps.ttest_1samp(logit(x), 0.0).confidence_interval(0.95)
    assert rate_ci(x)[1:] == (pytest.approx(expit(ci.low)), pytest.approx(expit(ci.high)))
