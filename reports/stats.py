"""Statistics behind every figure, table and claim: small pure functions over arrays.

Modelled on rliable's ``metrics.py``: each function takes plain arrays (shapes in the
docstring) and returns numbers or arrays; randomness comes from a seeded
``numpy.random.Generator`` so a report is a pure function of the store.

The seed is the unit of every inference: callers pass one number per seed (a per-seed
mean), never pooled episodes. Intervals and tests are Student/Welch t on those numbers
(calibrated at 3 seeds, where a percentile bootstrap over 3 values covers the mean only
about 75% of the time: measured by ``bench calibrate``), each from one scipy call in one
place: ``contrast_t`` (every t test, vectorized), ``t_interval`` (every Student t interval
of a mean). rliable supplies the IQM and the probability of improvement
(``rliable.metrics``; its ``library`` module, which holds the stratified bootstrap and
performance profiles, needs ``arch``, which does not import under pandas 3, so the
bootstraps are scipy's ``bootstrap``).
"""
from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from rliable import metrics as rly_metrics
from scipy import stats as sps

N_BOOT = 2000
LEVEL = 0.95
ALPHA = 0.05


def _clean(x: Sequence[float] | np.ndarray) -> np.ndarray:
    """The finite values of ``x`` as a flat float array."""
    a = np.asarray(x, dtype=np.float64)
    return a[np.isfinite(a)]


# ------------------------------------------------------------------ t statistics
@dataclass(frozen=True)
class TTest:
    """A (Welch) t statistic for a linear contrast of sample means.

    ``estimate`` = sum_k w_k mean(x_k) - null; ``lo``/``hi`` its two-sided ``level`` CI
    (of the contrast, null not subtracted); ``p_greater``/``p_less`` one-sided p-values of
    H1: contrast > null and H1: contrast < null. ``df`` is Welch-Satterthwaite (inf when
    the contrast has no variance, which makes the test exact).
    """

    estimate: float
    se: float
    df: float
    lo: float
    hi: float
    p_greater: float
    p_less: float

    @property
    def valid(self) -> bool:
        return bool(np.isfinite(self.estimate))


_NAN_TEST = TTest(*(np.nan,) * 7)


class Contrast(NamedTuple):
    """``TTest``'s fields as arrays: one test per position (``contrast_t``)."""

    estimate: np.ndarray
    se: np.ndarray
    df: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    p_greater: np.ndarray
    p_less: np.ndarray


def welch_parts(means: Sequence[np.ndarray] | np.ndarray, variances: Sequence[np.ndarray] | np.ndarray,
                counts: Sequence[int] | np.ndarray, weights: np.ndarray,
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Estimate, standard error and Welch-Satterthwaite df of sum_k w_k mean_k.

    ``means``/``variances`` (K, ...) per-sample means and unbiased variances (ddof 1),
    ``counts`` (K,) sample sizes (each >= 2), ``weights`` (K,). Trailing axes are
    vectorized over (e.g. percentiles). df = (sum c_k)^2 / sum c_k^2 / (n_k - 1) with
    c_k = w_k^2 s_k^2 / n_k; inf where the standard error is 0.
    """
    terms = list(zip(means, variances, counts, weights, strict=True))
    c = [(w * w * v / n, n) for _, v, n, w in terms]  # (c_k, n_k)
    est = sum(w * m for m, _, _, w in terms)
    var = sum(ck for ck, _ in c)
    denom = sum(ck * ck / (n - 1) for ck, n in c)
    with np.errstate(invalid="ignore"):  # 0 / 0 where nothing varies: df = inf below
        df = np.where(denom > 0, var * var / denom, np.inf)
    return np.asarray(est), np.sqrt(var), df


def contrast_t(samples: Sequence[np.ndarray], weights: Sequence[float], null: float = 0.0,
               level: float = LEVEL, axis: int = -1) -> Contrast:
    """The t test and ``level`` CI of the contrast sum_k w_k mean(x_k) against ``null``,
    vectorized: each sample's values run along ``axis`` (every other axis is a separate
    test: simulations, percentiles), and each field of the result is an array over those.

    One sample with weight +-1 is scipy's one-sample test (``ttest_1samp``), two with
    (1, -1) scipy's Welch test (``ttest_ind(equal_var=False)``; the null shifts the first
    sample); three or more (a gap, a slope) have no scipy test, so their Welch-Satterthwaite
    df comes from ``welch_parts`` and the test and CI from scipy's t distribution. A contrast
    without variance is decided exactly (p 0 or 1, df inf, the CI its estimate). No NaN
    handling: ``t_test`` cleans one test's samples.
    """
    xs = [np.asarray(s, dtype=np.float64) for s in samples]
    w = [float(x) for x in weights]
    est, se, df = welch_parts([x.mean(axis=axis) for x in xs], [x.var(axis=axis, ddof=1) for x in xs],
                              [x.shape[axis] for x in xs], np.asarray(w))
    with np.errstate(divide="ignore", invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # variance-free contrasts: decided below
        if w in ([1.0], [-1.0]):
            r = sps.ttest_1samp(w[0] * xs[0], null, axis=axis)
            ci, shift = r.confidence_interval(level), 0.0
        elif w == [1.0, -1.0]:
            r = sps.ttest_ind(xs[0] - null, xs[1], axis=axis, equal_var=False)
            ci, shift = r.confidence_interval(level), null
        else:
            r = None
            ci, shift = sps.t.interval(level, df, loc=est, scale=se), 0.0
        t, tdf = ((est - null) / se, df) if r is None else (r.statistic, r.df)
        lo, hi = np.asarray(ci[0]) + shift, np.asarray(ci[1]) + shift
        pg, pl = sps.t.sf(t, tdf), sps.t.cdf(t, tdf)
    d = est - null
    exact = se == 0.0
    return Contrast(d, se, np.where(exact, np.inf, tdf), np.where(exact, est, lo), np.where(exact, est, hi),
                    np.where(exact, (d <= 0).astype(float), pg), np.where(exact, (d >= 0).astype(float), pl))


def t_test(samples: Sequence[Sequence[float] | np.ndarray], weights: Sequence[float],
           null: float = 0.0, level: float = LEVEL) -> TTest:
    """Welch t test and CI of the contrast sum_k w_k mean(x_k) against ``null`` for one
    test (``contrast_t`` on its finite values).

    ``samples``: K 1-D arrays (n_k,), one number per seed. One sample with weight 1 is
    the one-sample t test; two with (1, -1) Welch's two-sample test; four with
    (1, -1, -1, 1) a difference of two gaps. Any sample with fewer than 2 finite values
    gives NaNs. A contrast without variance is decided exactly (p 0 or 1).
    """
    arrays = [_clean(s) for s in samples]
    if len(arrays) != len(weights):
        raise ValueError("samples and weights must have the same length")
    if not arrays or any(a.size < 2 for a in arrays):
        return _NAN_TEST
    return TTest(*(float(v) for v in contrast_t(arrays, weights, null, level)))


def t_interval(z: np.ndarray, level: float = LEVEL, axis: int = -1, omit_nan: bool = False
               ) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi): the Student t interval of the mean of ``z`` along ``axis``, scipy's
    ``ttest_1samp(...).confidence_interval``; ``omit_nan`` drops NaNs per slice (a slice
    with fewer than two values: NaN bounds)."""
    with warnings.catch_warnings(), np.errstate(invalid="ignore", divide="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)  # constant or short slices
        ci = sps.ttest_1samp(z, 0.0, axis=axis, nan_policy="omit" if omit_nan else "propagate"
                             ).confidence_interval(level)
    return np.asarray(ci.low), np.asarray(ci.high)


def mean_ci(x: Sequence[float] | np.ndarray, level: float = LEVEL) -> tuple[float, float, float]:
    """(mean, lo, hi): the Student t interval of the mean of ``x`` (n,), e.g. seed means
    (``scipy.stats.t.interval``).

    Calibrated for normal seed means at any n >= 2 (coverage in docs/decisions/0035);
    one value gives (v, nan, nan), none gives NaNs. NaNs are dropped. For a quantity with a
    range (a rate, a count) use ``rate_ci`` / ``positive_ci``: this one can leave it.
    """
    a = _clean(x)
    if a.size == 0:
        return np.nan, np.nan, np.nan
    m = float(a.mean())
    if a.size < 2:
        return m, np.nan, np.nan
    lo, hi = t_interval(a, level)
    return m, float(lo), float(hi)


# A seed at exactly 0% or 100% has no logit: it moves in by RATE_EPS (half a point), or by half
# the smallest distance of another seed from that end if that is smaller (collision rates of 1e-5);
# positive quantities at 0 move to POS_EPS before the log.
RATE_EPS = 0.005
POS_EPS = 1e-9
UNINFORMATIVE = 0.8  # a rate interval wider than 80 points says nothing useful about the mean


def _transformed_ci(a: np.ndarray, fwd: Callable[[np.ndarray], np.ndarray],
                    back: Callable[[np.ndarray], np.ndarray], level: float,
                    axis: int = -1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean of ``a`` along ``axis`` and the Student t interval of the mean of ``fwd(a)``
    mapped back by ``back``: inside ``back``'s range by construction. Where every value is
    equal the interval is that value."""
    lo, hi = t_interval(fwd(a), level, axis)
    mean = a.mean(axis=axis)
    same = a.max(axis=axis) == a.min(axis=axis)
    return _holding_mean(mean, np.where(same, mean, back(lo)), np.where(same, mean, back(hi)))


def _holding_mean(mean: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mean, lo, hi) with the interval widened to hold the mean it is printed beside. A
    logit interval is centred on the mean of the logits, which a skewed sample puts on one
    side of the plain mean: seeds at 99.8-100% gave 100.0% [99.8%, 99.9%]
    (docs/decisions/0248). Widening only adds coverage. (Cox's interval, ``_cox_ci``, is
    centred on a mean estimate and held the mean in 200,000 random lognormal samples.)"""
    return mean, np.minimum(lo, mean), np.maximum(hi, mean)


def _logit(x: np.ndarray) -> np.ndarray:
    """Logit of rates along the last axis, each row's 0s and 1s moved in by its own epsilon."""
    x = np.asarray(x, dtype=np.float64)
    inner = np.where((x > 0) & (x < 1), np.minimum(x, 1.0 - x), np.inf)
    eps = np.minimum(RATE_EPS, inner.min(axis=-1, keepdims=True) / 2.0)
    y = np.clip(x, eps, 1.0 - eps)
    return np.log(y / (1.0 - y))


def _expit(z: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-z))


def _log(x: np.ndarray) -> np.ndarray:
    return np.log(np.maximum(x, POS_EPS))


def rate_ci(x: Sequence[float] | np.ndarray, level: float = LEVEL) -> tuple[float, float, float]:
    """(mean, lo, hi) of a rate's seed values ``x`` (n,) in [0, 1]: the Student t interval
    on the logit scale (a seed at exactly 0 or 1 moved in by ``RATE_EPS`` or less), mapped
    back, so it lies inside [0, 1] by construction, never by cutting (docs/decisions/0232).
    Below two values: (mean, nan, nan)."""
    a = _clean(x)
    if a.size < 2:
        return (float(a[0]) if a.size else np.nan), np.nan, np.nan
    m, lo, hi = _transformed_ci(a, _logit, _expit, level)
    return float(m), float(lo), float(hi)


def _cox_ci(a: np.ndarray, level: float, axis: int = -1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean of ``a`` along ``axis`` and Cox's interval for the mean of a lognormal (with a t
    quantile): exp(mean(log a) + s^2 / 2 +- t sqrt(s^2 / n + s^4 / (2 (n - 1)))), s^2 the
    variance of log a; >= 0 by construction. Where every value is equal: that value."""
    z = _log(a)
    n = a.shape[axis]
    s2 = z.var(axis=axis, ddof=1)
    _, q = sps.t.interval(level, n - 1)
    centre = z.mean(axis=axis) + s2 / 2.0
    half = q * np.sqrt(s2 / n + s2 * s2 / (2.0 * (n - 1)))
    mean = a.mean(axis=axis)
    same = a.max(axis=axis) == a.min(axis=axis)
    with np.errstate(over="ignore"):
        return mean, np.where(same, mean, np.exp(centre - half)), np.where(same, mean, np.exp(centre + half))


def positive_ci(x: Sequence[float] | np.ndarray, level: float = LEVEL) -> tuple[float, float, float]:
    """(mean, lo, hi) of a count or other non-negative quantity's seed values ``x`` (n,):
    Cox's interval for a lognormal mean with a t quantile (``_cox_ci``), so lo >= 0 by
    construction. (A plain t interval on the log scale covers the median, not the mean: at
    24 seeds with a wide spread it covered 14-66% of the time; Cox's 92-96%, 3-24 seeds.)"""
    a = _clean(x)
    if a.size < 2:
        return (float(a[0]) if a.size else np.nan), np.nan, np.nan
    m, lo, hi = _cox_ci(a, level)
    return float(m), float(lo), float(hi)


def uninformative(lo: float, hi: float, span: float = 1.0) -> bool:
    """Whether an interval of a quantity whose range is ``span`` wide (a rate: 1) covers more
    than ``UNINFORMATIVE`` of it: its point says little."""
    return bool(np.isfinite(lo) and np.isfinite(hi) and hi - lo > UNINFORMATIVE * span)


COVERAGE_TARGET = 0.93  # a 95% interval whose simulated coverage is under this is not printed as one


def trusted(cov: float) -> bool:
    """Whether a simulated coverage, as printed (one decimal of a percent), reaches
    ``COVERAGE_TARGET``: only then is the interval printed as a 95% interval (no coverage,
    NaN, is no verdict on it). docs/decisions/0233."""
    return not np.isfinite(cov) or float(f"{100 * cov:.1f}") >= 100 * COVERAGE_TARGET


def untrusted_text(cov: float) -> str:
    """What a row prints instead of an interval whose coverage is not ``trusted``."""
    return f"interval not trusted: simulated coverage {cov:.1%} < {COVERAGE_TARGET:.0%}"


def coverage(kind: str, mean: float, sd: float, seeds: int, sims: int = 2000, level: float = LEVEL,
             seed: int = 0) -> float:
    """Simulated coverage of ``rate_ci`` (``kind`` "rate": seed values Beta with this mean and
    s.d.) or ``positive_ci`` ("positive": lognormal with this mean and s.d.) of the true mean,
    at ``seeds`` seeds: the interval's coverage at the data's own spread. NaN below two seeds
    or without a finite mean."""
    if seeds < 2 or not (np.isfinite(mean) and np.isfinite(sd)):
        return np.nan
    rng = np.random.default_rng(np.random.SeedSequence([seed, seeds, int(1e6 * mean) % 2**31]))
    if kind == "rate":
        m = float(np.clip(mean, 1e-3, 1 - 1e-3))
        v = min(max(sd, 1e-4) ** 2, 0.999 * m * (1 - m))
        k = m * (1 - m) / v - 1.0
        _, lo, hi = _transformed_ci(rng.beta(m * k, (1 - m) * k, size=(sims, seeds)), _logit, _expit, level)
    else:
        m = max(float(mean), POS_EPS)
        s2 = np.log1p((max(sd, 1e-12) / m) ** 2)
        _, lo, hi = _cox_ci(rng.lognormal(np.log(m) - s2 / 2, np.sqrt(s2), size=(sims, seeds)), level)
    return float(np.mean((lo <= m) & (m <= hi)))


def simultaneous_band(a: np.ndarray, b: np.ndarray, alpha: float = ALPHA, axis: int = 0
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Difference of mean curves a - b with one-sided simultaneous bounds (Bonferroni).

    ``a`` (S_a, G), ``b`` (S_b, G): one curve per seed (e.g. success quantiles at G
    percentiles), seeds along ``axis`` (the calibration passes (M, S, G) with axis 1).
    Returns (diff, lower, upper), each (G,) (or (M, G)): with probability >= 1 - alpha
    the true difference is >= ``lower`` at every one of the G points (and, separately,
    <= ``upper`` at every point). Per point a one-sided Welch t bound at level alpha / G:
    the two-sided 1 - 2 alpha / G interval of scipy's Welch test (``contrast_t``).
    Needs S_a, S_b >= 2.
    """
    a, b = np.asarray(a), np.asarray(b)
    if a.ndim != b.ndim or a.ndim < 2 or a.shape[-1] != b.shape[-1] or min(a.shape[axis], b.shape[axis]) < 2:
        raise ValueError(f"curves must be (S, G) with S >= 2 and equal G, got {a.shape} and {b.shape}")
    t = contrast_t([a, b], [1.0, -1.0], level=1.0 - 2.0 * alpha / a.shape[-1], axis=axis)
    return t.estimate, t.lo, t.hi


def zero_events_bound(n: int, alpha: float = ALPHA) -> float:
    """Exact (Clopper-Pearson) one-sided upper 1 - alpha bound on an event probability
    after 0 events in ``n`` independent trials: 1 - alpha^(1/n) (about 3/n)."""
    if n < 1:
        return np.nan
    return float(1.0 - alpha ** (1.0 / n))


# ------------------------------------------------------------------- rliable
def iqm(x: Sequence[float] | np.ndarray) -> float:
    """Interquartile mean (25% trimmed from each end), rliable's ``aggregate_iqm``."""
    a = _clean(x)
    if a.size == 0:
        return np.nan
    return float(rly_metrics.aggregate_iqm(a[:, None]))


def probability_of_improvement(x: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray) -> float:
    """P(X > Y) + P(X = Y) / 2 over seed scores ``x`` (n_x,), ``y`` (n_y,): rliable's
    ``probability_of_improvement`` (Mann-Whitney U / (n_x n_y)). NaN if a side is empty."""
    a, b = _clean(x), _clean(y)
    if a.size == 0 or b.size == 0:
        return np.nan
    return float(rly_metrics.probability_of_improvement(a[:, None], b[:, None]))


# ---------------------------------------------------------------- bootstrap
def bootstrap_ci(
    x: Sequence[float] | np.ndarray,
    statistic: Callable[[np.ndarray], np.ndarray] | None = None,
    n_boot: int = N_BOOT,
    level: float = LEVEL,
    seed: int = 0,
) -> tuple[float, float]:
    """Percentile bootstrap CI of ``statistic`` (default: mean) of a sample ``x`` (n,)
    (``scipy.stats.bootstrap``, method "percentile").

    For statistics without a t interval (IQM of many episodes); undercovers with few
    values, so never used over seeds. ``statistic`` maps (..., n) to (...,) along its last
    axis. NaNs are dropped; empty gives (nan, nan), values all equal v give (v, v).
    """
    a = _clean(x)
    if a.size == 0:
        return np.nan, np.nan
    if a.min() == a.max():
        return float(a[0]), float(a[0])
    stat = statistic or (lambda m: m.mean(axis=-1))
    res = sps.bootstrap((a,), lambda s, axis=-1: stat(np.moveaxis(s, axis, -1)), n_resamples=n_boot,
                        confidence_level=level, method="percentile", vectorized=True,
                        random_state=np.random.default_rng(seed))
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def t_band(curves: np.ndarray, level: float = LEVEL) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean curve and pointwise Student t band over runs for ``curves`` shaped (S, T).

    The shading of Fig. 1 and Fig. 2: per column, the mean over the runs (rows, e.g.
    seeds) and the t interval of that mean (``t_interval`` per column, NaNs omitted; a
    percentile bootstrap over 3 seeds covers only about 75%, ``bench calibrate``). A column
    with fewer than two values has NaN bounds (no band).
    """
    c = np.asarray(curves, dtype=np.float64)
    if c.ndim != 2 or c.shape[0] == 0:
        raise ValueError(f"curves must be (S, T) with S >= 1, got {c.shape}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns
        mean = np.nanmean(c, axis=0)
    lo, hi = t_interval(c, level, axis=0, omit_nan=True)
    return mean, lo, hi


# ------------------------------------------------------------------- curves
def percentile_curve(x: Sequence[float] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Episodes sorted by value against their percentile (Fig. 2's view).

    ``x`` (n,) one value per evaluation episode. Returns (pct, sorted), both (n,), with
    pct_i = 100 (i + 0.5) / n the midpoint (Hazen) plotting position of the i-th smallest.
    """
    a = np.sort(_clean(x))
    pct = 100.0 * (np.arange(a.size) + 0.5) / a.size  # empty stays empty
    return pct, a


def quantile_curve(x: Sequence[float] | np.ndarray, pct: np.ndarray) -> np.ndarray:
    """Values of ``x`` (n,) at percentiles ``pct`` (G,) in 0..100, consistent with
    ``percentile_curve`` (Hazen positions, linear in between, flat beyond the ends)."""
    a = _clean(x)
    if a.size == 0:
        return np.full(np.shape(pct), np.nan)
    return np.quantile(a, np.asarray(pct) / 100.0, method="hazen")


def smooth(y: Sequence[float] | np.ndarray, window: int) -> np.ndarray:
    """Trailing moving average of (T,) ``y`` over ``window`` points (fewer at the start),
    over the finite points of each window: a missing (NaN) episode leaves a gap of at most
    ``window`` points, never the rest of the curve (NaN where a window has no finite point).
    Without NaNs, the plain trailing mean (the same numbers)."""
    y = np.asarray(y, dtype=np.float64).reshape(-1)
    ok = np.isfinite(y)
    c = np.concatenate([[0.0], np.cumsum(np.where(ok, y, 0.0))])
    n = np.concatenate([[0], np.cumsum(ok)])
    k = np.arange(1, c.size)
    start = np.maximum(k - max(1, int(window)), 0)
    count = n[k] - n[start]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, (c[k] - c[start]) / count, np.nan)


def smoothing_window(n_episodes: int) -> int:
    """Window of the training-curve smoothing: 5% of training, 1..100 episodes."""
    return int(np.clip(round(0.05 * n_episodes), 1, 100))


# -------------------------------------------------------------- convergence
@dataclass(frozen=True)
class CurveShape:
    """Gain and final drift of one training curve (one seed)."""

    gain: float  # mean(last window) - mean(first window)
    drift: float  # OLS slope over the last window x its length: change across it
    window: int  # episodes per window


def curve_shape(rewards: Sequence[float] | np.ndarray, frac: float = 0.2,
                min_window: int = 10) -> CurveShape | None:
    """Gain and drift of a training curve ``rewards`` (T,) in episode order.

    Windows: the first and the last ``floor(frac T)`` episodes (the paper: "converges at
    around 1600" of 2000, so the last 20% is where it should be flat). None when a
    window would hold fewer than ``min_window`` episodes.
    """
    a = np.asarray(rewards)
    w = int(np.floor(frac * a.size))
    if w < max(min_window, 2):
        return None
    first, last = a[:w], a[a.size - w:]
    x = np.arange(w) - (w - 1) / 2.0  # centred: the OLS slope is x.y / x.x
    slope = float(np.dot(x, last) / np.dot(x, x))
    return CurveShape(float(last.mean() - first.mean()), slope * w, w)


@dataclass(frozen=True)
class Convergence:
    """Across-seed tests of ``convergence_test`` (each a one-sample t over seeds)."""

    gain: TTest  # E[gain] vs 0
    above: TTest  # E[drift - tol gain] vs 0: < 0 means not rising beyond tolerance
    below: TTest  # E[drift + tol gain] vs 0: > 0 means not falling beyond tolerance
    rel_tol: float
    window: int  # the shortest window of the seeds' curves

    def supported(self, alpha: float = ALPHA) -> bool:
        """Improved and stable: an intersection-union test, each part at ``alpha``."""
        return bool(self.gain.p_greater < alpha and self.above.p_less < alpha
                    and self.below.p_greater < alpha)

    def contradicted(self, alpha: float = ALPHA) -> bool:
        """Significantly no gain, still rising or falling beyond the tolerance."""
        return bool(self.gain.p_less < alpha or self.above.p_greater < alpha
                    or self.below.p_less < alpha)


def convergence_test(shapes: Sequence[CurveShape], rel_tol: float = 0.2) -> Convergence:
    """Has training improved and then stabilised, over seeds? (Fig. 1(b)'s claim).

    ``shapes``: one ``CurveShape`` per seed (>= 2). Improved: E[gain] > 0. Stable: the
    drift over the last window lies within +-``rel_tol`` x gain, tested as the
    equivalence E[drift - tol gain] < 0 and E[drift + tol gain] > 0; both are linear in
    per-seed numbers, so one-sample t tests over seeds decide them exactly (no episode
    autocorrelation enters: a seed is one number).
    """
    g = np.array([s.gain for s in shapes])
    d = np.array([s.drift for s in shapes])
    return Convergence(t_test([g], [1.0]), t_test([d - rel_tol * g], [1.0]),
                       t_test([d + rel_tol * g], [1.0]), rel_tol,
                       min((s.window for s in shapes), default=0))
