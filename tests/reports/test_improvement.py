"""The PoI interval's simulated coverage (reports/improvement.py, docs/decisions/0239)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from rliable import metrics as rly_metrics

from reports import improvement as imp
from reports.tables.leaderboard import _aggregate_lines, aggregate_frame


def test_poi_statistic__batched_over_data_sets_equals_rliable_per_data_set() -> None:
    rng = np.random.default_rng(3)
    a, b = rng.random((4, 3, 2)), rng.random((4, 5, 2))  # 4 data sets, 3 and 5 seeds, 2 configurations
    a[0, 0, 0] = b[0, 0, 0]  # a tie counts a half
    got = imp.poi_statistic(2)(*[a[:, :, j] for j in range(2)], *[b[:, :, j] for j in range(2)])
    assert got == pytest.approx([rly_metrics.probability_of_improvement(a[i], b[i]) for i in range(4)], abs=0)


def test_stratified_band__a_batch_of_data_sets_gives_one_interval_each() -> None:
    rng = np.random.default_rng(4)
    cols = [rng.random((6, 3)) for _ in range(4)]  # 6 data sets, 3 seeds, 2 + 2 configurations
    lo, hi = imp.stratified_band(cols, imp.poi_statistic(2), batch=100)
    assert lo.shape == hi.shape == (6,) and (lo <= hi).all()
    point = imp.poi_statistic(2)(*cols)
    assert ((lo <= point + 1e-12) & (point <= hi + 1e-12)).mean() > 0.8


def test_poi_coverage__a_wide_spread_at_three_seeds_is_under_the_target_and_five_seeds_do_better() -> None:
    rng = np.random.default_rng(5)
    means_a, means_b = rng.uniform(0.2, 0.8, 10), rng.uniform(0.2, 0.8, 10)
    def seeds(means: np.ndarray, n: int) -> np.ndarray:  # 10 configurations, seeds spread 0.25 about each mean
        return np.clip(means + 0.25 * rng.standard_normal((n, means.size)), 0.01, 0.99)
    few = imp.poi_coverage(seeds(means_a, 3), seeds(means_b, 3), sims=300)
    assert 0.6 < few < 0.93  # h49s measured 84-92% at the full grid's 3 vs 3 seeds
    # a constant method (a planner) far above every draw of the other: every data set's PoI is the truth
    assert imp.poi_coverage(np.ones((3, 10)), seeds(means_b, 3)) == 1.0
    assert np.isnan(imp.poi_coverage(np.ones((1, 10)), seeds(means_b, 3)))
    # the coverage is the interval's: a bootstrap band pinned to its point estimate covers far less
    real = imp.stratified_band
    imp.stratified_band = lambda cols, stat, seed=0, level=0.95, batch=None: (stat(*cols), stat(*cols))
    try:
        assert imp.poi_coverage(seeds(means_a, 3), seeds(means_b, 3), sims=300) < 0.2
    finally:
        imp.stratified_band = real


def test_leaderboard__prints_the_poi_coverage_and_withholds_an_interval_under_93_percent() -> None:
    rng = np.random.default_rng(6)
    rows = [dict(method=m, n_robots=n, loss_p=0.2, execution="argmax", seed=s, episode=0,
                 success_rate=float(np.clip(base + 0.3 * rng.standard_normal(), 0, 1)))
            for m, base in (("decentralized", 0.6), ("hierarchical", 0.4)) for n in (10, 20, 30, 40, 50, 60)
            for s in range(3)]
    iqm, poi = aggregate_frame(pd.DataFrame(rows))
    assert poi["poi_cov"].between(0, 1).all()
    a = poi.set_index(["method", "over"])["poi_cov"]
    assert a[("decentralized", "hierarchical")] == a[("hierarchical", "decentralized")]
    text = "\n".join(_aggregate_lines(iqm, poi, "one-shot"))
    for r in poi.itertuples():
        if round(100 * r.poi_cov, 1) < 93:
            assert f"{100 * r.poi:.1f}% (interval not trusted: simulated coverage {r.poi_cov:.1%} < 93%)" in text
        else:
            assert f"(coverage {r.poi_cov:.1%})" in text


def test_poi_coverage__ties_with_a_planner_at_100_percent_are_not_simulated() -> None:
    planner = np.ones((3, 4))
    learned = np.array([[1.0, 0.5, 0.4, 0.6], [0.9, 0.6, 0.3, 0.5], [0.95, 0.55, 0.35, 0.2]])  # one tie at 100%
    assert np.isnan(imp.poi_coverage(planner, learned))  # the Beta model says "never tied": it cannot judge
    assert imp.poi_coverage(planner, np.minimum(learned, 0.99)) == 1.0
