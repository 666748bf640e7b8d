"""The method-agnostic leaderboard (reports/tables/leaderboard.py) and ``--against`` (reports/data/against.py).

Aggregates are checked against rliable's own metrics on matrices worked out by hand; the
merge is checked end to end on tiny stores: a run of the new method merged with a run of
the baselines gives exactly the leaderboard of one run that trained every method, and a
run whose settings or scenarios differ is refused naming the first mismatch.
"""
from __future__ import annotations

from itertools import permutations
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from rliable import metrics as rly_metrics
from scipy import stats

from bench.design.cells import Cell
from bench.design.grids import Grid
from envs.errors import BenchError
from reports.data.against import merge_against
from reports.data.store import load_store
from reports.improvement import poi_statistic as _poi
from reports.improvement import stratified_band as _stratified_band
from reports.improvement import stratified_ci as _stratified_ci
from reports.stats import iqm, rate_ci
from reports.tables.leaderboard import (
    _profile,
    aggregate_frame,
    leaderboard_frame,
    safety_frame,
    score_matrices,
)
from tests.bench.conftest import toy_spec, write_finished_store
from tests.bench.toy_method import TOY_PATH


def _evals(rows: list[tuple[str, int, float, str, int, float]]) -> pd.DataFrame:
    """Eval rows (method, N, p, execution, seed, success), one episode each."""
    return pd.DataFrame([dict(method=m, n_robots=n, loss_p=p, execution=e, seed=s, success_rate=v, episode=0)
                         for m, n, p, e, s, v in rows])


def test_iqm_and_improvement__equal_rliables_metrics_on_a_hand_made_matrix() -> None:
    x = np.array([[0.1, 0.9], [0.5, 0.7], [0.3, 0.2], [0.8, 0.4]])  # 4 seeds x 2 configurations
    y = np.array([[0.2, 0.6], [0.4, 0.7], [0.1, 0.3]])
    assert [iqm(row) for row in x] == pytest.approx([float(rly_metrics.aggregate_iqm(r[None, :])) for r in x])
    # per configuration: #(x > y) + #ties / 2 over 12 pairs: (8 + 0.5) / 12 and (6 + 0.5) / 12
    assert _poi(2)(*x.T, *y.T) == pytest.approx(rly_metrics.probability_of_improvement(x, y))
    assert rly_metrics.probability_of_improvement(x, y) == pytest.approx((8.5 / 12 + 6.5 / 12) / 2)


def test_profile__the_fraction_of_runs_above_tau_with_a_stratified_band() -> None:
    x = np.array([[0.1, 0.9], [0.5, 0.7], [0.3, 0.2]])  # 3 seeds x 2 configurations
    taus = np.array([0.0, 0.25, 0.6, 0.9])
    cols = [x[:, 0], x[:, 1]]
    # scores 0.1 0.5 0.3 | 0.9 0.7 0.2: above 0 all 6, above 0.25 four, above 0.6 two, above 0.9 none
    assert _profile(taus)(*cols) == pytest.approx([1.0, 4 / 6, 2 / 6, 0.0])
    lo, hi = _stratified_band(cols, _profile(taus))
    assert lo.shape == hi.shape == (4,)
    assert lo[0] == hi[0] == 1.0 and lo[3] == hi[3] == 0.0  # no resample moves these
    assert lo[1] < 4 / 6 < hi[1] and lo[2] < 2 / 6 < hi[2]
    # each configuration resampled on its own: configuration 1's seeds never land in 0's
    same = [np.array([0.2, 0.2, 0.2]), np.array([0.8, 0.8, 0.8])]
    lo, hi = _stratified_band(same, _profile(np.array([0.5])))
    assert lo[0] == hi[0] == 0.5  # a pooled bootstrap would spread it over [0, 1]
    lo, hi = _stratified_band([np.array([0.4])], _profile(taus))
    assert lo.ndim == 0 and np.isnan(lo)  # one seed: no band


def test_leaderboard__ranks_within_a_configuration_and_planners_rank_with_every_mode() -> None:
    ev = _evals([("a", 4, 0.2, "argmax", s, v) for s, v in enumerate((0.2, 0.4))]
                + [("b", 4, 0.2, "argmax", s, v) for s, v in enumerate((0.6, 0.8))]
                + [("a", 4, 0.2, "sample", s, v) for s, v in enumerate((0.9, 0.9))]
                + [("b", 4, 0.2, "sample", s, v) for s, v in enumerate((0.1, 0.1))]
                + [("p", 4, 0.2, "planner", s, 0.5) for s in range(2)])
    board = leaderboard_frame(ev).set_index(["execution", "method"])
    assert board.loc[("argmax", "b"), "rank"] == 1 and board.loc[("argmax", "a"), "rank"] == 3
    assert board.loc[("sample", "a"), "rank"] == 1 and board.loc[("sample", "b"), "rank"] == 3
    assert board.loc[("planner", "p"), "rank"] == 2
    assert board.loc[("argmax", "a"), "success"] == pytest.approx(0.3)
    assert board.loc[("argmax", "a"), "seeds"] == 2


def test_safety_frame__means_over_seeds_and_no_correction_rate_where_no_filter_ran() -> None:
    def row(method: str, filt: bool, seed: int, episode: int, corr: float, coll: float) -> dict[str, object]:
        return dict(method=method, n_robots=4, loss_p=0.2, execution="argmax", seed=seed, episode=episode,
                    safety_filter=filt, collision_rate=coll, correction_rate=corr, fallback_rate=np.nan if not filt
                    else 0.5, mean_candidates=np.nan if not filt else 3.0, payload_scalars_per_step=12.0)
    ev = pd.DataFrame([row("f", True, 0, 0, 0.1, 0.0), row("f", True, 0, 1, 0.3, 0.0), row("f", True, 1, 0, 0.5, 0.0),
                       row("n", False, 0, 0, 0.0, 0.2), row("n", False, 1, 0, 0.0, 0.4)])
    out = safety_frame(ev).set_index("method")
    assert out.loc["f", "correction_rate"] == pytest.approx((0.2 + 0.5) / 2)  # per-seed means, then over seeds
    assert out.loc["f", "seeds"] == 2 and out.loc["f", "mean_candidates"] == pytest.approx(3.0)
    assert np.isnan(out.loc["n", "correction_rate"]) and np.isnan(out.loc["n", "fallback_rate"])
    assert out.loc["n", "collision_rate"] == pytest.approx(0.3)


def test_score_matrices__only_configurations_every_method_covers_and_their_common_seeds() -> None:
    ev = _evals([("a", n, 0.2, "argmax", s, 0.1 * s) for n in (4, 6) for s in range(3)]
                + [("b", 4, 0.2, "argmax", s, 0.5) for s in range(2)])
    mats, cfgs, used = score_matrices(ev, "argmax")
    assert cfgs == [(4, 0.2)]  # N = 6 has no b
    assert mats["a"].shape == (3, 1) and mats["b"].shape == (2, 1) and used == {"a": 3, "b": 2}
    iqm, poi = aggregate_frame(ev)
    assert set(iqm["method"]) == {"a", "b"} and len(poi) == 2


def _store(tmp: Path, name: str, cells: list[Cell]) -> Path:
    out = tmp / name
    write_finished_store(out, Grid(name, "test", tuple(cells)))
    return out


def _cells(method: str, **kw) -> list[Cell]:
    base = {"method": method} if method != "pibt" else {"method": "pibt", "episodes": 0, "params": {"eval_chunk": 2}}
    spec = toy_spec(**kw) if method != "pibt" else {**toy_spec(**kw), **base}
    spec["method"] = method
    return [Cell.make(**{**spec, "seed": s, "n_robots": n}) for n in (4, 6) for s in range(2)]


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    tmp = tmp_path_factory.mktemp("against")
    new, base = _cells(TOY_PATH, params={"lr": 0.2}), _cells("pibt")
    return {"new": _store(tmp, "new", new), "base": _store(tmp, "base", base),
            "joint": _store(tmp, "joint", base + new),
            "long": _store(tmp, "long", _cells(TOY_PATH, horizon=14)),
            "chunked": _store(tmp, "chunked", _cells(TOY_PATH, params={"eval_chunk": 1}))}


def test_against__a_merged_run_gives_the_leaderboard_of_a_run_that_trained_every_method(runs) -> None:
    merged = merge_against(load_store(runs["new"]), runs["base"])
    joint = load_store(runs["joint"])
    pd.testing.assert_frame_equal(leaderboard_frame(merged.eval), leaderboard_frame(joint.eval))
    for a, b in zip(aggregate_frame(merged.eval), aggregate_frame(joint.eval), strict=True):
        pd.testing.assert_frame_equal(a, b)
    assert set(merged.cells["cell_id"]) == set(joint.cells["cell_id"])
    assert any("merged with 4 done cells" in p for p in merged.problems)


@pytest.mark.parametrize("other, message", [
    ("long", "horizon differs at N=4 p=0.2: 12 here, 14 there"),
    ("chunked", "scenario differs at N=4 p=0.2 seed 0 episode 1"),
])
def test_against__settings_or_scenarios_that_differ_are_refused_naming_the_first(runs, other, message) -> None:
    with pytest.raises(BenchError, match=message):
        merge_against(load_store(runs["new"]), runs[other])


def test_against__a_configuration_the_reference_lacks_is_refused(runs, tmp_path: Path) -> None:
    only4 = _store(tmp_path, "only4", [c for c in _cells("pibt") if c.n_robots == 4])
    with pytest.raises(BenchError, match="no done cell at N=6 p=0.2"):
        merge_against(load_store(runs["new"]), only4)


# --- the exact frames the report pages and the README's headline numbers are built from ---
BOARD_COLUMNS = ["n_robots", "loss_p", "execution", "method", "label", "seeds", "success", "success_lo",
                 "success_hi", "success_cov", "correction_rate", "fallback_rate", "rank"]


def test_leaderboard__columns_order_and_the_logit_t_interval_over_seeds_inside_a_rates_range() -> None:
    ev = _evals([("decentralized", 4, 0.2, "sample", s, v) for s, v in enumerate((0.4, 0.5, 0.6))]
                + [("hierarchical", 4, 0.2, "sample", s, v) for s, v in enumerate((0.1, 0.2, 0.3))]
                + [("hierarchical", 4, 0.2, "argmax", s, v) for s, v in enumerate((0.0, 0.3, 0.0))]
                + [("decentralized", 4, 0.2, "argmax", 0, 0.6)]
                + [("pibt", 4, 0.2, "planner", 0, 1.0)]
                + [("hierarchical", 2, 0.6, "argmax", 0, 0.4)])
    board = leaderboard_frame(ev)
    assert list(board.columns) == BOARD_COLUMNS and board["rank"].dtype == np.int64
    # N, then p, then argmax < sample < planner, then the paper's method before the baselines
    assert list(zip(board["n_robots"], board["execution"], board["method"], strict=True)) == [
        (2, "argmax", "hierarchical"), (4, "argmax", "hierarchical"), (4, "argmax", "decentralized"),
        (4, "sample", "hierarchical"), (4, "sample", "decentralized"), (4, "planner", "pibt")]
    assert board["label"].tolist()[-3:] == ["Hierarchical (ours)", "Decentralized", "PIBT"]
    row = board.set_index(["n_robots", "execution", "method"]).loc[(4, "sample", "decentralized")]
    z = np.log(np.array([0.4, 0.5, 0.6]) / np.array([0.6, 0.5, 0.4]))  # the t interval on the logit scale
    half = stats.t.ppf(0.975, 2) * z.std(ddof=1) / np.sqrt(3)
    lo, hi = 1 / (1 + np.exp(half)), 1 / (1 + np.exp(-half))
    assert (row["success"], row["success_lo"], row["success_hi"]) == pytest.approx((0.5, lo, hi))
    assert 0.9 <= row["success_cov"] <= 1.0  # its simulated coverage at this spread
    argmax = board.set_index(["n_robots", "execution", "method"]).loc[(4, "argmax", "hierarchical")]
    assert 0.0 < argmax["success_lo"] < 0.1 < argmax["success_hi"] < 1.0  # inside [0, 1], not cut
    one = board.iloc[0]
    assert one["seeds"] == 1 and np.isnan(one["success_lo"]) and np.isnan(one["success_hi"])


def test_leaderboard__ties_share_the_best_rank_and_a_planner_ranks_against_the_first_learned_mode() -> None:
    ev = _evals([("a", 4, 0.2, "argmax", 0, 0.5), ("b", 4, 0.2, "argmax", 0, 0.5), ("c", 4, 0.2, "argmax", 0, 0.1),
                 ("a", 4, 0.2, "sample", 0, 0.9), ("b", 4, 0.2, "sample", 0, 0.8), ("c", 4, 0.2, "sample", 0, 0.7),
                 ("p", 4, 0.2, "planner", 0, 0.3)])
    rank = leaderboard_frame(ev).set_index(["execution", "method"])["rank"]
    assert (rank[("argmax", "a")], rank[("argmax", "b")], rank[("planner", "p")], rank[("argmax", "c")]) == (1, 1, 3, 4)
    assert [rank[("sample", m)] for m in "abc"] == [1, 2, 3]  # the planner (rank 4 here) has its argmax rank
    three = leaderboard_frame(_evals([(m, 4, 0.2, "argmax", 0, 0.5) for m in "abc"]
                                     + [("d", 4, 0.2, "argmax", 0, 0.1)]))
    assert three["rank"].tolist() == [1, 1, 1, 4]  # "min": not the average rank 2
    unscored = leaderboard_frame(_evals([("a", 4, 0.2, "argmax", 0, np.nan), ("b", 4, 0.2, "argmax", 0, 0.2)]))
    assert dict(zip(unscored["method"], unscored["rank"], strict=True)) == {"a": 0, "b": 1}  # no value: unranked
    only = leaderboard_frame(_evals([("p", 4, 0.2, "planner", 0, 0.3), ("q", 4, 0.2, "planner", 0, 0.6)]))
    assert dict(zip(only["method"], only["rank"], strict=True)) == {"q": 1, "p": 2}
    empty = leaderboard_frame(_evals([]).reindex(columns=["method", "n_robots", "loss_p", "execution", "seed",
                                                          "success_rate", "episode"]))
    assert list(empty.columns) == BOARD_COLUMNS and empty.empty and empty["rank"].dtype == np.int64


def test_aggregates__iqm_and_improvement_per_mode_over_shared_configurations_with_intervals_over_seeds() -> None:
    seeds = range(3)
    ev = _evals([("decentralized", n, 0.2, "argmax", s, 0.8 + 0.05 * s) for n in (4, 6) for s in seeds]
                + [("hierarchical", n, 0.2, "argmax", s, 0.1 + 0.05 * s) for n in (4, 6) for s in seeds]
                + [("ic3net", n, 0.2, "argmax", s, 0.4 + 0.1 * s) for n in (4, 6, 8) for s in seeds]
                + [("hierarchical", n, 0.2, "sample", s, 0.95) for n in (4, 6) for s in seeds]
                + [("decentralized", n, 0.2, "sample", s, 0.05) for n in (4, 6) for s in seeds]
                + [("ic3net", n, 0.2, "sample", s, 0.5) for n in (4, 6) for s in seeds])
    iqm, poi = aggregate_frame(ev)
    assert list(iqm.columns) == ["execution", "method", "label", "configurations", "seeds", "iqm", "seed_iqm",
                                 "iqm_lo", "iqm_hi", "iqm_cov"]
    assert list(poi.columns) == ["execution", "method", "over", "label", "over_label", "configurations", "poi",
                                 "poi_lo", "poi_hi", "poi_cov"]
    # the paper's method first, then the baselines in their legend order; argmax before sample
    assert list(zip(iqm["execution"], iqm["method"], strict=True)) == [
        (e, m) for e in ("argmax", "sample") for m in ("hierarchical", "decentralized", "ic3net")]
    a = iqm.set_index(["execution", "method"])
    assert (a["configurations"] == 2).all() and (a["seeds"] == 3).all()  # N = 8: ic3net only
    mat = np.array([[0.8, 0.8], [0.85, 0.85], [0.9, 0.9]])
    assert a.loc[("argmax", "decentralized"), "iqm"] == pytest.approx(rly_metrics.aggregate_iqm(mat))
    assert a.loc[("argmax", "decentralized"), "iqm_lo"] <= 0.85 <= a.loc[("argmax", "decentralized"), "iqm_hi"]
    _, lo, hi = rate_ci(np.array([0.8, 0.85, 0.9]))  # each seed's IQM over the configurations, then over seeds
    assert a.loc[("argmax", "decentralized"), ["iqm_lo", "iqm_hi"]].tolist() == pytest.approx([lo, hi])
    assert a.loc[("sample", "hierarchical"), "iqm"] == pytest.approx(0.95)  # each mode its own matrix
    assert a.loc[("sample", "hierarchical"), ["iqm_lo", "iqm_hi"]].tolist() == pytest.approx([0.95, 0.95])
    assert len(poi) == 2 * 6  # every ordered pair of 3 methods, per mode
    p = poi.set_index(["execution", "method", "over"])
    for e in ("argmax", "sample"):
        for x, y in permutations(("hierarchical", "decentralized", "ic3net"), 2):
            assert p.loc[(e, x, y), "poi"] + p.loc[(e, y, x), "poi"] == pytest.approx(1.0)
    # every seed of decentralized above every seed of hierarchical: 1 with no room to move
    assert p.loc[("argmax", "decentralized", "hierarchical"), ["poi", "poi_lo", "poi_hi"]].tolist() == [1.0, 1.0, 1.0]
    assert p.loc[("argmax", "hierarchical", "decentralized"), "over_label"] == "Decentralized"
    # the bootstrap is seeded: the same frames twice
    again = aggregate_frame(ev)
    pd.testing.assert_frame_equal(iqm, again[0])
    pd.testing.assert_frame_equal(poi, again[1])


def test_score_matrices__each_mode_alone_and_a_method_without_common_seeds_left_out_not_the_rest() -> None:
    ev = _evals([("a", 4, 0.2, "argmax", s, 0.1) for s in range(2)]
                + [("a", 4, 0.2, "sample", s, 0.9) for s in range(2)]
                + [("b", 4, 0.2, "argmax", 0, 0.2), ("b", 6, 0.2, "argmax", 1, 0.2)]
                + [("c", n, 0.2, "argmax", s, 0.3) for n in (4, 6) for s in range(2)]
                + [("a", 6, 0.2, "argmax", s, 0.1) for s in range(2)])
    mats, cfgs, used = score_matrices(ev, "argmax")
    assert cfgs == [(4, 0.2), (6, 0.2)]  # the last method (c) covers both, b and a too
    assert set(mats) == {"a", "c"} and used == {"a": 2, "c": 2}  # b: no seed at both N
    assert (mats["a"] == 0.1).all()  # argmax rows only, not sample's 0.9
    one_short = _evals([(m, n, 0.2, "argmax", 0, 0.5) for m in "ab" for n in (4, 6)]
                       + [("c", 4, 0.2, "argmax", 0, 0.5)])
    assert score_matrices(one_short, "argmax")[1] == [(4, 0.2)]  # c's own configurations, not the others'
    disjoint = _evals([("a", 4, 0.2, "argmax", 0, 0.5), ("b", 6, 0.2, "argmax", 0, 0.5)])
    assert score_matrices(disjoint, "argmax") == ({}, [], {})


def test_safety_frame__columns_and_rows_sorted_whatever_order_the_rows_came_in() -> None:
    def row(method: str, n: int, seed: int) -> dict[str, object]:
        return dict(method=method, n_robots=n, loss_p=0.2, execution="argmax", seed=seed, episode=0,
                    safety_filter=False, collision_rate=0.1, correction_rate=0.0, fallback_rate=np.nan,
                    mean_candidates=np.nan, payload_scalars_per_step=1.0)
    out = safety_frame(pd.DataFrame([row("pibt", 6, 0), row("decentralized", 6, 1), row("decentralized", 4, 0)]))
    assert list(out.columns) == ["method", "label", "n_robots", "loss_p", "execution", "seeds", "collision_rate",
                                 "correction_rate", "fallback_rate", "mean_candidates", "payload_scalars_per_step"]
    assert list(zip(out["method"], out["n_robots"], strict=True)) == [("decentralized", 4), ("decentralized", 6),
                                                                      ("pibt", 6)]
    assert out["label"].tolist() == ["Decentralized", "Decentralized", "PIBT"]


def _pooled_mean(*cols: np.ndarray, axis: int = -1) -> np.ndarray:
    """A batched statistic of a matrix whose columns are ``cols``: the mean of every value."""
    return np.concatenate([np.moveaxis(c, axis, -1) for c in cols], axis=-1).mean(axis=-1)


def test_stratified_band__two_seeds_are_enough_seeded_and_nan_on_both_sides_below() -> None:
    cols = [np.array([0.1, 0.5]), np.array([0.2, 0.9])]
    lo, hi = _stratified_band(cols, _pooled_mean)
    assert np.isfinite(lo) and np.isfinite(hi) and lo < hi
    # the published protocol, so the committed reports rebuild byte for byte: 2,000 percentile
    # resamples at 95%, seeded with 0
    varied = [np.array([0.11, 0.52, 0.37, 0.94, 0.23, 0.68]), np.array([0.05, 0.81, 0.44, 0.29, 0.99, 0.6])]
    ref = stats.bootstrap(varied, _pooled_mean, n_resamples=2000, confidence_level=0.95, method="percentile",
                          vectorized=True, random_state=np.random.default_rng(0)).confidence_interval
    assert _stratified_band(varied, _pooled_mean) == (ref.low, ref.high)
    assert _stratified_ci(varied, _pooled_mean) == (ref.low, ref.high)
    lo, hi = _stratified_band([np.array([0.1, 0.5]), np.array([0.3])], _pooled_mean)
    assert np.isnan(lo) and np.isnan(hi)
