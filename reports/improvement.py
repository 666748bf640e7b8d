"""Probability of improvement across configurations, its stratified bootstrap interval and
that interval's simulated coverage: one place for all three (docs/decisions/0239).

* ``poi_statistic(k)``: rliable's ``probability_of_improvement`` of X's ``k`` configuration
  columns over Y's, batched for ``scipy.stats.bootstrap``;
* ``stratified_band`` / ``stratified_ci``: the 95% percentile CI with each configuration's
  seeds resampled on their own (the stratified bootstrap, ``scipy.stats.bootstrap``);
* ``poi_coverage``: how often that interval covers the true PoI when each configuration's
  seeds are drawn from a model fitted to the data's own per-configuration mean and s.d.
  (Beta for a rate, lognormal for throughput, a point mass where every seed agreed): the
  simulation that gave decision 0233's numbers, in one vectorized call.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import stats as sps

from reports.stats import LEVEL, N_BOOT, POS_EPS

__all__ = ["POI_SIMS", "poi_coverage", "poi_statistic", "stratified_band", "stratified_ci"]

POI_SIMS = 300  # simulated data sets behind each printed PoI coverage (MC s.e. about 1.5 points near 93%)
_GRID = 4000  # quantile grid of the true PoI's integral


def stratified_band(samples: list[np.ndarray], statistic: Callable, seed: int = 0, level: float = LEVEL,
                    batch: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """95% percentile CI of ``statistic(*samples, axis=-1)`` with each sample (a
    configuration's seeds) resampled on its own: the stratified bootstrap
    (``scipy.stats.bootstrap``, vectorized: every sample arrives shaped (..., n), leading axes
    a batch of data sets). A statistic of k values returns them first, shaped (k, ...): then
    (k,) bounds. NaN where a configuration has fewer than 2 seeds. ``batch``: resamples per
    vectorized call (memory only; it changes the order of the draws, so the report's own
    intervals use None)."""
    if any(np.shape(s)[-1] < 2 for s in samples):
        return np.array(np.nan), np.array(np.nan)
    res = sps.bootstrap(samples, statistic, n_resamples=N_BOOT, confidence_level=level, method="percentile",
                        vectorized=True, random_state=np.random.default_rng(seed), batch=batch, axis=-1)
    return np.asarray(res.confidence_interval.low), np.asarray(res.confidence_interval.high)


def stratified_ci(samples: list[np.ndarray], statistic: Callable, seed: int = 0) -> tuple[float, float]:
    """``stratified_band`` of a statistic of one value."""
    lo, hi = stratified_band(samples, statistic, seed)
    return float(lo), float(hi)


def poi_statistic(k: int) -> Callable:
    """rliable's ``probability_of_improvement`` of X's first ``k`` columns over Y's ``k``,
    batched: per configuration P(X > Y) + P(X = Y) / 2 over all seed pairs, averaged."""
    def stat(*cols: np.ndarray, axis: int = -1) -> np.ndarray:
        per = []
        for x, y in zip(cols[:k], cols[k:], strict=True):
            x, y = np.moveaxis(x, axis, -1)[..., :, None], np.moveaxis(y, axis, -1)[..., None, :]
            pairs = x.shape[-2] * y.shape[-1]  # wins + ties / 2 = (pairs + wins - losses) / 2: sums of halves,
            wins_less_losses = np.sign(x - y).sum(axis=(-2, -1))  # exact, so the same numbers as a mean of floats
            per.append((0.5 * pairs + 0.5 * wins_less_losses) / pairs)
        return np.mean(per, axis=0)
    return stat


def _model(column: np.ndarray, kind: str):
    """The seed distribution of one configuration: a frozen scipy distribution at the column's
    mean and s.d. (Beta for ``kind`` "rate", as ``reports.stats.coverage``; lognormal for
    "positive"), or the float itself where every seed agreed (no spread to model)."""
    mean, sd = float(np.mean(column)), float(np.std(column, ddof=1))
    if sd == 0.0:
        return mean
    if kind == "rate":
        m = float(np.clip(mean, 1e-3, 1 - 1e-3))
        v = min(sd ** 2, 0.999 * m * (1 - m))
        c = m * (1 - m) / v - 1.0
        return sps.beta(m * c, (1 - m) * c)
    m = max(mean, POS_EPS)
    s2 = np.log1p((sd / m) ** 2)
    return sps.lognorm(np.sqrt(s2), scale=m * np.exp(-s2 / 2))


def _true_poi(x, y) -> float:
    """P(X > Y) + P(X = Y) / 2 of two models of ``_model`` (continuous ones tie with probability 0):
    the integral of F_Y over X's quantiles on a fine grid."""
    if isinstance(x, float) and isinstance(y, float):
        return 1.0 if x > y else 0.5 if x == y else 0.0
    if isinstance(x, float):
        return float(y.cdf(x))
    if isinstance(y, float):
        return float(x.sf(y))
    u = (np.arange(_GRID) + 0.5) / _GRID
    return float(np.mean(y.cdf(x.ppf(u))))


def _draw(model, rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    return np.full(shape, model) if isinstance(model, float) else model.rvs(size=shape, random_state=rng)


def poi_coverage(a: np.ndarray, b: np.ndarray, kind: str = "rate", sims: int | None = None, seed: int = 0) -> float:
    """Simulated coverage of ``stratified_ci(..., poi_statistic(k))`` for the PoI of X over Y,
    ``a`` (X's seeds x k configurations), ``b`` (Y's seeds x k): ``sims`` data sets of the same
    shape drawn from ``_model`` of each column, each one's interval computed exactly as the
    report's (one batched ``scipy.stats.bootstrap`` call), against the models' true PoI. The
    coverage of Y over X is the same (the interval mirrors). NaN below two seeds a side, and
    where the models make every configuration's order certain but the data do not (seeds tied
    with a planner at exactly 0% or 100%, which no Beta draws): no simulation can speak for it.
    Otherwise a rate at 0% or 100% is modelled just inside, as ``reports.stats.coverage`` does."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    sims = POI_SIMS if sims is None else sims
    if min(a.shape[0], b.shape[0]) < 2 or a.shape[1] == 0:
        return np.nan
    k = a.shape[1]
    rng = np.random.default_rng(np.random.SeedSequence([seed, a.shape[0], b.shape[0], k]))
    ma, mb = [_model(a[:, j], kind) for j in range(k)], [_model(b[:, j], kind) for j in range(k)]
    per = [_true_poi(x, y) for x, y in zip(ma, mb, strict=True)]
    if all(t in (0.0, 1.0) for t in per):  # the models order every configuration alike in every draw:
        seen = poi_statistic(k)(*[a[:, j] for j in range(k)], *[b[:, j] for j in range(k)])
        return 1.0 if seen == np.mean(per) else np.nan  # covered always, or data (ties at 0 or 1) the models can't draw
    truth = float(np.mean(per))
    cols = ([_draw(m, rng, (sims, a.shape[0])) for m in ma] + [_draw(m, rng, (sims, b.shape[0])) for m in mb])
    lo, hi = stratified_band(cols, poi_statistic(k), seed=seed, batch=100)
    return float(np.mean((lo <= truth + 1e-12) & (truth - 1e-12 <= hi)))
