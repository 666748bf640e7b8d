"""The pooled test of a claim across its configurations: an exact sign test
(``scipy.stats.binomtest``) on the direction each check's estimate points (docs/decisions/0231).

Each check with an estimate counts once: toward the claim or against it
(``paper.claims.sides``). Under the claim's boundary every direction is a fair coin, so the
number pointing toward the claim is Binomial(k, 1/2): **supported** when it is significantly
more than half at ``TEST_ALPHA`` (one-sided), **contradicted** when significantly less at
``TEST_ALPHA``, **undecided** otherwise. One test per claim, so neither side needs a
Bonferroni share. It answers "does the claim's direction hold across its configurations?",
not "does it hold at each one" (the per-check verdicts and their combination). Execution
modes of one configuration share seeds, a positive dependence the test ignores;
``bench calibrate`` measures its error rates at the run's own spread (checks drawn
independently) beside the checks'.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from scipy import stats as sps

from paper.claims.sides import AGAINST, TOWARD
from paper.claims.verdicts import CONTRADICTED, INCONCLUSIVE, NOT_ENOUGH, SUPPORTED, TEST_ALPHA

__all__ = ["Pooled", "sign_test", "MIN_DECIDABLE"]


def _min_decidable(alpha: float = TEST_ALPHA) -> int:
    """The fewest checks at which k of k pointing one way is significant at ``alpha``."""
    k = 1
    while 0.5**k >= alpha:
        k += 1
    return k


MIN_DECIDABLE = _min_decidable()  # 7 at 0.0125


@dataclass(frozen=True)
class Pooled:
    """A claim's sign test: checks pointing toward and against it, both one-sided p-values
    and the verdict."""

    toward: int
    against: int
    p_toward: float
    p_against: float
    verdict: str

    def text(self) -> str:
        """"16 of 18 checks point against the claim; sign test p(toward) = 1, p(against) = 0.00066: contradicted"."""
        n = self.toward + self.against
        if n == 0:
            return "no sign test (no check with an estimate on a one-sided claim)"
        lead, k = (TOWARD, self.toward) if self.toward >= self.against else (AGAINST, self.against)
        note = f" (a sign test over fewer than {MIN_DECIDABLE} checks cannot reach {TEST_ALPHA:g})" \
            if n < MIN_DECIDABLE else ""
        return (f"{k} of {n} checks point {lead}; sign test p(toward) = {self.p_toward:.2g}, "
                f"p(against) = {self.p_against:.2g}: {self.verdict}{note}")


def sign_test(points: Sequence[str], alpha: float = TEST_ALPHA) -> Pooled:
    """``points``: each check's direction (``TOWARD``, ``AGAINST``, or "" for a check
    without an estimate or with a two-sided claim, left out: at a band's edge an estimate
    leaves the band on either side, so its direction is no fair coin there)."""
    k = sum(p == TOWARD for p in points)
    j = sum(p == AGAINST for p in points)
    if k + j == 0:
        return Pooled(0, 0, float("nan"), float("nan"), NOT_ENOUGH)
    pt = float(sps.binomtest(k, k + j, 0.5, alternative="greater").pvalue)
    pa = float(sps.binomtest(k, k + j, 0.5, alternative="less").pvalue)
    verdict = SUPPORTED if pt < alpha else CONTRADICTED if pa < alpha else INCONCLUSIVE
    return Pooled(k, j, pt, pa, verdict)
