"""Where a check's estimate and its printed 95% interval sit against the claim: the words of
an *undecided* check (docs/decisions/0231).

A claim of a check is a region of its tested quantity (a difference above 0, a rate below
its bound, a mean inside the paper's band). An undecided check says which way its
estimate points (toward the claim: inside the region; against it: outside) and what its
interval excludes: the claim (the interval lies outside the region), the claim's negation
(inside it), or neither (it spans both). Only the last, with power under 50%, reads "this
design could not have decided it": an interval that excludes the claim is evidence
against it, however short of a contradiction at the claim's Bonferroni level.

The intervals are the ones the check's numbers print (``reports.stats``: a Welch t
interval of a contrast, ``rate_ci`` of a rate, ``positive_ci`` of a count), computed from
the same per-seed arrays the check decides on, like ``paper.claims.claim_power``.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from paper.claims.verdicts import CONV_REL_TOL, FINAL_FRAC, MIN_SEEDS, per_seed_means
from reports.stats import curve_shape, positive_ci, rate_ci, t_test

__all__ = ["Side", "side_below", "side_contrast", "side_convergence", "side_curves", "side_near", "NO_SIDE"]

TOWARD, AGAINST = "toward the claim", "against the claim"
EXCLUDES_CLAIM, EXCLUDES_NEGATION, SPANS_BOTH = "the claim", "the claim's negation", "neither (spans both)"


@dataclass(frozen=True)
class Side:
    """A check's estimate, its printed 95% interval [lo, hi], and the claim's region
    (``low``, ``high``) of that quantity (either end may be infinite)."""

    estimate: float
    lo: float
    hi: float
    low: float
    high: float
    also: bool = True  # a second part of the claim the estimate meets (convergence: a drift within tolerance)

    @property
    def known(self) -> bool:
        return bool(np.isfinite(self.estimate))

    @property
    def one_sided(self) -> bool:
        """The claim's region has one finite end (the pooled sign test's premise)."""
        return bool(np.isinf(self.low) != np.isinf(self.high))

    @property
    def points(self) -> str:
        """``TOWARD`` when the estimate lies in the claim's region, else ``AGAINST`` ("" unknown)."""
        if not self.known:
            return ""
        return TOWARD if self.also and self.low < self.estimate < self.high else AGAINST

    @property
    def excludes(self) -> str:
        """What the interval excludes: ``EXCLUDES_CLAIM``, ``EXCLUDES_NEGATION`` or ``SPANS_BOTH``
        ("" without an interval)."""
        if not (np.isfinite(self.lo) and np.isfinite(self.hi)):
            return ""
        if self.hi <= self.low or self.lo >= self.high:
            return EXCLUDES_CLAIM
        if self.low < self.lo and self.hi < self.high:
            return EXCLUDES_NEGATION
        return SPANS_BOTH

    def region(self) -> str:
        """The claim's region in words: "> 0", "< 0.08", "in 1.9..5.69"."""
        if np.isinf(self.high):
            return f"> {self.low:.3g}"
        if np.isinf(self.low):
            return f"< {self.high:.3g}"
        return f"in {self.low:.3g}..{self.high:.3g}"


NO_SIDE = Side(float("nan"), float("nan"), float("nan"), -np.inf, np.inf)


def _finite(x: np.ndarray) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    return a[np.isfinite(a)]


def side_contrast(groups: Sequence[np.ndarray], weights: Sequence[float]) -> Side:
    """A Welch contrast of per-seed means claimed > 0 (A above B, a wider gap, a rising slope)."""
    gs = [_finite(g) for g in groups]
    if min(g.size for g in gs) < MIN_SEEDS:
        return NO_SIDE
    t = t_test(gs, list(weights))
    return Side(t.estimate, t.lo, t.hi, 0.0, np.inf) if t.valid else NO_SIDE


def side_curves(h: list[np.ndarray], i: list[np.ndarray]) -> Side:
    """``check_curves``: its mean-success difference, claimed > 0."""
    return side_contrast([per_seed_means(h), per_seed_means(i)], [1.0, -1.0])


def side_below(m: np.ndarray, bound: float, rate: bool = True) -> Side:
    """A per-seed quantity claimed below ``bound``: its mean and ``rate_ci`` (a rate) or
    ``positive_ci`` (a count)."""
    a = _finite(m)
    if a.size < MIN_SEEDS:
        return NO_SIDE
    est, lo, hi = (rate_ci if rate else positive_ci)(a)
    return Side(est, lo, hi, -np.inf, bound)


def side_near(m: np.ndarray, low: float, high: float) -> Side:
    """A per-seed count claimed inside the paper's band [low, high]: its ``positive_ci``."""
    a = _finite(m)
    if a.size < MIN_SEEDS:
        return NO_SIDE
    est, lo, hi = positive_ci(a)
    return Side(est, lo, hi, low, high)


def side_convergence(curves: list[np.ndarray], rel_tol: float = CONV_REL_TOL) -> Side:
    """``check_convergence``: the seeds' gain, claimed > 0, with its t interval; a mean drift
    beyond +-``rel_tol`` x gain makes the estimate point against the claim."""
    if len(curves) < MIN_SEEDS:
        return NO_SIDE
    shapes = [curve_shape(c, FINAL_FRAC) for c in curves]
    if any(s is None for s in shapes):
        return NO_SIDE
    g = np.array([s.gain for s in shapes if s is not None])
    d = np.array([s.drift for s in shapes if s is not None])
    t = t_test([g], [1.0])
    stable = abs(float(d.mean())) < rel_tol * float(g.mean())
    return Side(t.estimate, t.lo, t.hi, 0.0, np.inf, stable)
