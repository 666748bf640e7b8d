"""The stated effect and the power of each claim check (``paper.claims.power`` over the same
per-seed arrays the check's kernel decides on).

Stated effects (docs/decisions/0153): success +``EFFECT_SUCCESS`` (10
points) at every percentile; final reward +10% of the baseline's mean final reward (the
paper prints no reward numbers); a rate below its bound: the paper's own Table I value
where it prints one, else half the bound; convergence: the seeds' own mean gain with no
drift; Table I's values: the paper's value itself; the search trend: the slope of the
paper's own Table I column.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from functools import wraps
from typing import Any

import numpy as np

from paper.claims.power import Power, power_of, weakest
from paper.claims.verdicts import BAND_PCT, BAND_TOL, TEST_ALPHA, per_seed_means
from paper.claims.verdicts_bounds import NEAR_TOL, trend_weights
from reports.stats import curve_shape, quantile_curve

EFFECT_SUCCESS = 0.10
REWARD_FRAC = 0.10
_SKIP = [False]


@contextmanager
def skipped() -> Iterator[None]:
    """Checks computed inside carry no power (``NO_POWER``): the simulations of
    ``bench calibrate`` decide thousands of checks and read only their verdicts."""
    _SKIP[0] = True
    try:
        yield
    finally:
        _SKIP[0] = False


def _unless_skipped(fn: Callable[..., Power]) -> Callable[..., Power]:
    @wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Power:
        from paper.claims.power import NO_POWER

        return NO_POWER if _SKIP[0] else fn(*args, **kwargs)
    return wrapper


def _level(x: np.ndarray) -> float:
    """|mean| of the finite values of ``x`` (NaN, without a warning, when there are none)."""
    a = np.asarray(x, dtype=np.float64)
    a = a[np.isfinite(a)]
    return abs(float(a.mean())) if a.size else float("nan")


@_unless_skipped
def power_greater(a: np.ndarray, b: np.ndarray) -> Power:
    """``check_greater`` on final rewards: A above B by 10% of B's mean."""
    effect = REWARD_FRAC * _level(b)
    return power_of([a, b], [1.0, -1.0], effect, f"+{effect:.3g} final reward (10% of the baseline's)")


@_unless_skipped
def power_success(a: np.ndarray, b: np.ndarray) -> Power:
    """``check_greater`` on per-seed mean success (a run's method above a baseline): +``EFFECT_SUCCESS``."""
    return power_of([a, b], [1.0, -1.0], EFFECT_SUCCESS, f"+{EFFECT_SUCCESS:g} mean success")


@_unless_skipped
def power_gap(groups: Sequence[np.ndarray]) -> Power:
    """``check_gap`` (hier large, dec large, hier small, dec small): the gap at the large N
    wider by 10% of decentralized's mean final reward there."""
    effect = REWARD_FRAC * _level(groups[1])
    return power_of(list(groups), [1.0, -1.0, -1.0, 1.0], effect,
                    f"a gap wider by {effect:.3g} (10% of decentralized's final reward)")


@_unless_skipped
def power_curves(h: list[np.ndarray], i: list[np.ndarray]) -> Power:
    """``check_curves``: hierarchical +0.1 success at every percentile; the mean test and
    each percentile's band bound (margin 0.1 + ``BAND_TOL`` at TEST_ALPHA / G) must all pass."""
    words = f"+{EFFECT_SUCCESS:g} success at every percentile"
    parts = [power_of([per_seed_means(h), per_seed_means(i)], [1.0, -1.0], EFFECT_SUCCESS, words)]
    qh = np.stack([quantile_curve(x, BAND_PCT) for x in h])
    qi = np.stack([quantile_curve(x, BAND_PCT) for x in i])
    for g in range(BAND_PCT.size):
        parts.append(power_of([qh[:, g], qi[:, g]], [1.0, -1.0], EFFECT_SUCCESS + BAND_TOL, words,
                              alpha=TEST_ALPHA / BAND_PCT.size))
    return weakest(words, *parts)


@_unless_skipped
def power_convergence(curves: list[np.ndarray], rel_tol: float, frac: float) -> Power:
    """``check_convergence``: the seeds' own mean gain G, no drift; gain > 0 and both
    sides of the equivalence |drift| < rel_tol gain must pass (margins G, rel_tol G)."""
    shapes = [curve_shape(c, frac) for c in curves]
    g = np.array([s.gain for s in shapes if s is not None])
    d = np.array([s.drift for s in shapes if s is not None])
    gm = float(g.mean())
    words = f"its own mean gain {gm:.3g} with no drift"
    return weakest(words, power_of([g], [1.0], gm, words),
                   power_of([rel_tol * g - d], [1.0], rel_tol * gm, words),
                   power_of([d + rel_tol * g], [1.0], rel_tol * gm, words))


@_unless_skipped
def power_below(m: np.ndarray, bound: float, truth: float, words: str) -> Power:
    """A per-seed rate ``m`` below ``bound`` when its true mean is ``truth``."""
    return power_of([m], [1.0], bound - truth, words)


@_unless_skipped
def power_near(m: np.ndarray, target: float, tol: float = NEAR_TOL) -> Power:
    """``check_near`` when the true mean is the paper's ``target``: both sides pass."""
    words = f"a true mean equal to the paper's {target:.3g}"
    return weakest(words, power_of([m], [1.0], tol * target, words),
                   power_of([m], [-1.0], tol * target, words))


@_unless_skipped
def power_trend(groups: Sequence[np.ndarray], ns: Sequence[int], slope: float) -> Power:
    """``check_trend`` when the true slope is ``slope`` per robot."""
    return power_of(list(groups), list(trend_weights(ns)), slope,
                    f"a slope of {slope:.3g} per robot (the paper's Table I)")
