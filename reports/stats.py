"""Statistics behind every figure, table and claim: small pure functions over arrays.

Modelled on rliable's ``metrics.py``: each function takes plain arrays (shapes in the
docstring), returns numbers or arrays, and draws its randomness from a ``seed`` so a
report is a pure function of the store. Confidence intervals are percentile bootstrap
intervals (Efron); the resampling unit (seeds or evaluation episodes) is the caller's
choice and is always reported next to the interval.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

N_BOOT = 2000
LEVEL = 0.95


def _clean(x: Sequence[float] | np.ndarray) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64).reshape(-1)
    return a[np.isfinite(a)]


def bootstrap_ci(
    x: Sequence[float] | np.ndarray,
    statistic: Callable[[np.ndarray], np.ndarray] | None = None,
    n_boot: int = N_BOOT,
    level: float = LEVEL,
    seed: int = 0,
) -> tuple[float, float]:
    """Percentile bootstrap CI of ``statistic`` (default: mean) of a sample ``x`` (n,).

    ``statistic`` maps resamples (n_boot, n) to (n_boot,). NaNs are dropped; an empty
    sample gives (nan, nan), a single value v gives (v, v).
    """
    a = _clean(x)
    if a.size == 0:
        return float("nan"), float("nan")
    stat = statistic or (lambda m: m.mean(axis=-1))
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, a.size, size=(n_boot, a.size))
    reps = np.asarray(stat(a[idx]), dtype=np.float64)
    alpha = (1.0 - level) / 2.0
    lo, hi = np.quantile(reps, [alpha, 1.0 - alpha])
    return float(lo), float(hi)


def bootstrap_contrast_ci(
    samples: Sequence[Sequence[float] | np.ndarray],
    weights: Sequence[float],
    n_boot: int = N_BOOT,
    level: float = LEVEL,
    seed: int = 0,
) -> tuple[float, float, float]:
    """Point estimate and CI of sum_k w_k mean(x_k) with each sample resampled independently.

    ``samples`` are K 1-D arrays (n_k,); ``weights`` (K,). A difference of means is
    weights (1, -1); a difference of two gaps is (1, -1, -1, 1). Returns (estimate, lo,
    hi); any empty sample gives NaNs.
    """
    arrays = [_clean(s) for s in samples]
    if len(arrays) != len(weights):
        raise ValueError("samples and weights must have the same length")
    if any(a.size == 0 for a in arrays):
        return float("nan"), float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    est = float(sum(w * a.mean() for w, a in zip(weights, arrays, strict=True)))
    reps = np.zeros(n_boot)
    for w, a in zip(weights, arrays, strict=True):
        reps += w * a[rng.integers(0, a.size, size=(n_boot, a.size))].mean(axis=1)
    alpha = (1.0 - level) / 2.0
    lo, hi = np.quantile(reps, [alpha, 1.0 - alpha])
    return est, float(lo), float(hi)


def bootstrap_band(
    curves: np.ndarray, n_boot: int = 1000, level: float = LEVEL, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean curve and pointwise bootstrap band over runs for ``curves`` shaped (S, T).

    Runs (rows, e.g. seeds) are resampled with replacement; returns (mean, lo, hi), each
    (T,). With S = 1 the band collapses onto the curve. NaN entries are ignored per column.
    """
    c = np.asarray(curves, dtype=np.float64)
    if c.ndim != 2 or c.shape[0] == 0:
        raise ValueError(f"curves must be (S, T) with S >= 1, got {c.shape}")
    mean = np.nanmean(c, axis=0)
    if c.shape[0] == 1:
        return mean, mean.copy(), mean.copy()
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, c.shape[0], size=(n_boot, c.shape[0]))
    with np.errstate(all="ignore"):
        reps = np.nanmean(c[idx], axis=1)  # (n_boot, T)
    alpha = (1.0 - level) / 2.0
    lo, hi = np.nanquantile(reps, [alpha, 1.0 - alpha], axis=0)
    return mean, lo, hi


def iqm(x: Sequence[float] | np.ndarray) -> float:
    """Interquartile mean: the mean of the middle 50% (25% trimmed from each end, as rliable)."""
    a = _clean(x)
    if a.size == 0:
        return float("nan")
    return float(sps.trim_mean(a, proportiontocut=0.25))


def percentile_curve(x: Sequence[float] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Episodes sorted by value against their percentile (Fig. 2's view).

    ``x`` (n,) one value per evaluation episode. Returns (pct, sorted), both (n,), with
    pct_i = 100 (i + 0.5) / n the midpoint (Hazen) plotting position of the i-th smallest.
    """
    a = np.sort(_clean(x))
    pct = 100.0 * (np.arange(a.size) + 0.5) / max(a.size, 1)
    return pct, a


def quantile_curve(x: Sequence[float] | np.ndarray, pct: np.ndarray) -> np.ndarray:
    """Values of ``x`` (n,) at percentiles ``pct`` (G,) in 0..100, consistent with
    ``percentile_curve`` (Hazen positions, linear in between, flat beyond the ends)."""
    a = _clean(x)
    if a.size == 0:
        return np.full(np.shape(pct), np.nan)
    return np.quantile(a, np.asarray(pct, dtype=np.float64) / 100.0, method="hazen")


def smooth(y: Sequence[float] | np.ndarray, window: int) -> np.ndarray:
    """Trailing moving average of (T,) ``y`` over ``window`` points (fewer at the start)."""
    a = np.asarray(y, dtype=np.float64).reshape(-1)
    w = max(1, int(window))
    if a.size == 0 or w == 1:
        return a.copy()
    c = np.concatenate([[0.0], np.cumsum(a)])
    k = np.arange(1, a.size + 1)
    start = np.maximum(k - w, 0)
    return (c[k] - c[start]) / (k - start)


def smoothing_window(n_episodes: int) -> int:
    """Window of the training-curve smoothing: 5% of training, 1..100 episodes."""
    return int(np.clip(round(0.05 * n_episodes), 1, 100))


def mann_whitney_greater(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray) -> float:
    """One-sided Mann-Whitney U p-value for H1: values of ``a`` tend to exceed those of ``b``.

    NaN if either sample is empty or every value is identical (no evidence either way).
    """
    x, y = _clean(a), _clean(b)
    if x.size == 0 or y.size == 0 or np.ptp(np.concatenate([x, y])) == 0:
        return float("nan")
    return float(sps.mannwhitneyu(x, y, alternative="greater").pvalue)


def slope_ci(y: Sequence[float] | np.ndarray, level: float = LEVEL) -> tuple[float, float, float]:
    """OLS slope of (T,) ``y`` against its index, with a t-based CI: (slope, lo, hi).

    Needs T >= 3; a perfectly straight line gives a zero-width interval.
    """
    a = np.asarray(y, dtype=np.float64).reshape(-1)
    if a.size < 3:
        return float("nan"), float("nan"), float("nan")
    x = np.arange(a.size, dtype=np.float64)
    res = sps.linregress(x, a)
    half = float(sps.t.ppf(0.5 + level / 2.0, a.size - 2) * res.stderr)
    return float(res.slope), float(res.slope - half), float(res.slope + half)


@dataclass(frozen=True)
class Convergence:
    """Outcome of ``convergence_test`` for one training curve (rewards per episode)."""

    converged: bool
    gain: float  # mean(last window) - mean(first window)
    gain_lo: float  # 95% CI of the gain (bootstrap over the windows' episodes)
    drift: float  # OLS slope over the last window x its length: change across the window
    drift_lo: float
    drift_hi: float
    tolerance: float  # allowed |drift|: ``rel_tol`` x |gain|
    window: int  # episodes per window


def convergence_test(
    rewards: Sequence[float] | np.ndarray, frac: float = 0.2, rel_tol: float = 0.2,
    min_window: int = 10, seed: int = 0,
) -> Convergence | None:
    """Has a training curve improved and then stabilised? (the claim behind Fig. 1(b)).

    ``rewards`` (T,) episode rewards in training order. With windows of ``frac`` T episodes
    at the start and at the end: *improved* if the 95% bootstrap CI of mean(last) -
    mean(first) lies above 0; *stable* if the 95% CI of the drift over the last window
    (OLS slope x window length) lies inside +-``rel_tol`` x gain (an equivalence test:
    a noisy curve cannot pass by having a wide interval). Converged = both. Returns None
    when a window would hold fewer than ``min_window`` episodes.
    """
    a = np.asarray(rewards, dtype=np.float64).reshape(-1)
    w = int(np.floor(frac * a.size))
    if w < min_window:
        return None
    first, last = a[:w], a[-w:]
    gain, g_lo, _ = bootstrap_contrast_ci([last, first], [1.0, -1.0], seed=seed)
    slope, s_lo, s_hi = slope_ci(last)
    tol = rel_tol * abs(gain)
    drift_lo, drift_hi = s_lo * w, s_hi * w
    converged = bool(g_lo > 0 and -tol <= drift_lo and drift_hi <= tol)
    return Convergence(converged, gain, g_lo, slope * w, drift_lo, drift_hi, tol, w)
