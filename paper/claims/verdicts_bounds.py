"""Claim tests for Table I's statements that are bounds, values and trends: a rate below
a bound, a mean near the paper's printed value, a mean rising with team size. Per-seed
arrays in, (verdict, numbers, test) out, like ``paper.claims.verdicts``; each a
one-sample / Welch t over per-seed means (``reports.stats.t_test``).

- ``check_below``: supported when the per-seed mean is significantly below ``bound``
  (at ``TEST_ALPHA``), contradicted when significantly above it (at ``contra_alpha``).
- ``check_near``: an equivalence test (two one-sided t tests) of the mean against the
  paper's value within +-``NEAR_TOL`` of it: supported when both sides reject at
  ``TEST_ALPHA``; contradicted when the mean is significantly outside the band on either
  side, each side at ``contra_alpha`` / 2 (a union of two tests).
- ``check_trend``: the OLS slope of the group means on N (a Welch contrast of the K
  groups' per-seed means, weights (N_k - mean N) / sum (N_k - mean N)^2) is > 0.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from paper.claims.verdicts import (
    CONTRADICTED,
    INCONCLUSIVE,
    MIN_SEEDS,
    NOT_ENOUGH,
    SUPPORTED,
    TEST_ALPHA,
    contra_note,
    decide,
    seeds_msg,
)
from reports.stats import positive_ci, rate_ci, t_test, uninformative

NEAR_TOL = 0.5  # "as in Table I": within +-50% of the paper's printed value


def _g(x: float) -> str:
    return f"{x:.3g}"


def _finite(x: np.ndarray) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    return a[np.isfinite(a)]


def check_below(m: np.ndarray, bound: float, what: str, contra_alpha: float = TEST_ALPHA,
                pct: bool = True) -> tuple[str, str, str]:
    """Per-seed ``m`` (S,) below ``bound``: one-sample t against it (``pct``: show rates in %)."""
    m = _finite(m)
    if m.size < MIN_SEEDS:
        return NOT_ENOUGH, seeds_msg(m.size), "-"
    t = t_test([-m], [1.0], null=-bound)  # contrast -mean - (-bound) > 0: mean below the bound
    f = (lambda x: f"{_g(100 * x)}%") if pct else _g
    # the interval shown: a rate's inside [0, 1], a count's >= 0, by construction (the test is the t above)
    _, lo, hi = rate_ci(m) if pct else positive_ci(m)
    vague = "; uninformative" if pct and uninformative(lo, hi) else ""
    nums = (f"{what} {f(m.mean())} [95% CI {f(lo)}, {f(hi)}{vague}] vs {f(bound)}; one-sided p = "
            f"{_g(t.p_greater)}")
    return (decide(t, contra_alpha=contra_alpha), nums,
            f"one-sample t over {m.size} seeds against {f(bound)}{contra_note(contra_alpha)}")


def check_near(m: np.ndarray, target: float, what: str, contra_alpha: float = TEST_ALPHA,
               tol: float = NEAR_TOL) -> tuple[str, str, str]:
    """Per-seed ``m`` (S,) within +-``tol`` x ``target`` of the paper's ``target`` (TOST)."""
    m = _finite(m)
    if m.size < MIN_SEEDS:
        return NOT_ENOUGH, seeds_msg(m.size), "-"
    lo_b, hi_b = target * (1 - tol), target * (1 + tol)
    above = t_test([m], [1.0], null=lo_b)  # > lower edge
    below = t_test([m], [1.0], null=hi_b)  # < upper edge
    if not above.valid:
        return NOT_ENOUGH, "no finite values", "-"
    if above.p_less < contra_alpha / 2 or below.p_greater < contra_alpha / 2:
        verdict = CONTRADICTED
    elif above.p_greater < TEST_ALPHA and below.p_less < TEST_ALPHA:
        verdict = SUPPORTED
    else:
        verdict = INCONCLUSIVE
    _, lo, hi = positive_ci(m)  # a count's interval, >= 0 by construction (the tests are the t above)
    nums = (f"{what} {_g(m.mean())} [95% CI {_g(lo)}, {_g(hi)}] vs paper {_g(target)} "
            f"(band {_g(lo_b)}..{_g(hi_b)}); p(above the band) = {_g(below.p_greater)}, "
            f"p(below it) = {_g(above.p_less)}")
    return verdict, nums, (f"equivalence, two one-sided t over {m.size} seeds, +-{tol:.0%} of the "
                           f"paper's value{contra_note(contra_alpha)}")


def trend_weights(ns: Sequence[float]) -> np.ndarray:
    """(K,) weights of the OLS slope of K group means on ``ns``: (N_k - mean) / sum (N - mean)^2."""
    x = np.asarray(ns, dtype=np.float64)
    c = x - x.mean()
    return c / np.dot(c, c)


def check_trend(groups: Sequence[np.ndarray], ns: Sequence[int], what: str,
                contra_alpha: float = TEST_ALPHA) -> tuple[str, str, str]:
    """``groups``: one per-seed array per team size ``ns`` (K >= 2): slope > 0?"""
    gs = [_finite(g) for g in groups]
    if min(g.size for g in gs) < MIN_SEEDS:
        return NOT_ENOUGH, seeds_msg(*(g.size for g in gs)), "-"
    t = t_test(gs, list(trend_weights(ns)))
    means = ", ".join(f"{n}: {_g(g.mean())}" for n, g in zip(ns, gs, strict=True))
    nums = (f"{what} by N ({means}); slope {_g(t.estimate)} per robot [95% CI {_g(t.lo)}, "
            f"{_g(t.hi)}], one-sided p = {_g(t.p_greater)}")
    return (decide(t, contra_alpha=contra_alpha), nums,
            f"Welch t on the OLS slope of {len(gs)} per-seed means on N{contra_note(contra_alpha)}")
