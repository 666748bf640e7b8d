"""Power of a claim check at its own seed counts and observed spread, and the seeds that
80% power would need.

Every claim test that is a Welch / one-sample t on a linear contrast of per-seed means
(``reports.stats.t_test``) has an exact power under normal seed values: the t statistic
is noncentral t with noncentrality effect / se (``scipy.stats.nct``), se and the
Welch-Satterthwaite df taken from the observed per-seed standard deviations. A check
that needs several such tests at once (an intersection: the curve test's mean and band,
the convergence test's three parts, an equivalence test's two sides) has at most the
smallest of their powers; ``bound`` says so and the text reads "<=".

Pure functions over arrays; ``paper.claims.claims`` writes the text beside each verdict.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

from paper.claims.verdicts import MIN_SEEDS, TEST_ALPHA
from reports.stats import welch_parts

TARGET = 0.8  # the power whose seed count is reported
LOW = 0.5  # below this an undecided verdict whose interval spans both sides says the design could not decide it
MAX_SEEDS = 1000  # seed counts searched for TARGET ("> 1000" beyond)
COULD_NOT = "undecided: this design could not have decided it"


@dataclass(frozen=True)
class Power:
    """Power of a check to detect ``effect`` (a stated truth, in words) at its seeds, and
    the equal seed count per side that reaches ``TARGET`` (None: more than ``MAX_SEEDS``)."""

    power: float
    seeds_80: int | None
    effect: str
    bound: bool = False  # True: an upper bound (an intersection of tests)

    def text(self) -> str:
        """"power 23% to detect +0.1 success; 80% power needs 14 seeds per side"."""
        if not np.isfinite(self.power):
            return "-"
        need = f"> {MAX_SEEDS}" if self.seeds_80 is None else str(self.seeds_80)
        return (f"power {'<= ' if self.bound else ''}{self.power:.0%} to detect {self.effect}; "
                f"{TARGET:.0%} power needs {need} seeds per side")


NO_POWER = Power(float("nan"), None, "-")


def contrast_power(sds: Sequence[float], counts: Sequence[int] | np.ndarray, weights: Sequence[float],
                   effect: float, alpha: float = TEST_ALPHA) -> np.ndarray:
    """Power of the one-sided level-``alpha`` (default: the checks' ``TEST_ALPHA``) Welch t test of sum_k w_k mean_k >
    0 when
    the true contrast is ``effect``; ``sds`` (K,) per-group seed standard deviations,
    ``counts`` (K,) or (K, M) seed counts (M designs at once). Returns () or (M,).
    A contrast without variance is decided exactly: power 1 if ``effect`` > 0, else 0."""
    n = np.asarray(counts, dtype=np.float64)
    k = len(weights)
    shape = (k,) + (1,) * (n.ndim - 1)
    v = np.reshape(np.square(np.asarray(sds, dtype=np.float64)), shape) * np.ones_like(n)
    w = np.asarray(weights, dtype=np.float64)
    _, se, df = welch_parts(np.zeros_like(n), v, n, w.reshape(shape))
    with np.errstate(divide="ignore", invalid="ignore"):
        crit = sps.t.isf(alpha, df)
        p = sps.nct.sf(crit, df, effect / se)
    return np.where(se > 0, p, float(effect > 0))


def seeds_for(sds: Sequence[float], weights: Sequence[float], effect: float,
              alpha: float = TEST_ALPHA, target: float = TARGET) -> int | None:
    """Smallest equal seed count n per group (``MIN_SEEDS``..``MAX_SEEDS``: fewer seeds
    are never decided) whose power is >= ``target``."""
    ns = np.arange(MIN_SEEDS, MAX_SEEDS + 1)
    p = contrast_power(sds, np.tile(ns, (len(weights), 1)), weights, effect, alpha)
    hit = np.flatnonzero(p >= target)
    return int(ns[hit[0]]) if hit.size else None


def sd(x: np.ndarray) -> float:
    """Seed standard deviation of the finite values of ``x`` (ddof 1; NaN below two)."""
    a = np.asarray(x, dtype=np.float64)
    a = a[np.isfinite(a)]
    return float(a.std(ddof=1)) if a.size >= 2 else float("nan")


def power_of(samples: Sequence[np.ndarray], weights: Sequence[float], effect: float,
             words: str, alpha: float = TEST_ALPHA) -> Power:
    """``Power`` of the contrast test over ``samples`` (one per-seed array per group) at
    their own counts and spreads, for a true contrast ``effect`` (described by ``words``)."""
    sds = [sd(s) for s in samples]
    if not all(np.isfinite(sds)):
        return NO_POWER
    counts = [int(np.isfinite(s).sum()) for s in samples]
    return Power(float(contrast_power(sds, counts, weights, effect, alpha)),
                 seeds_for(sds, weights, effect, alpha), words)


def weakest(words: str, *powers: Power) -> Power:
    """An intersection of tests (each part's ``Power``) against one truth ``words``: at
    most the smallest power, and at least the largest seed count any part needs (None if
    one needs more than ``MAX_SEEDS``)."""
    if any(not np.isfinite(p.power) for p in powers):
        return NO_POWER
    low = min(powers, key=lambda p: p.power)
    needs = [p.seeds_80 for p in powers]
    seeds = None if None in needs else max(n for n in needs if n is not None)
    return Power(low.power, seeds, words, bound=True)
