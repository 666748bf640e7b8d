"""The method-agnostic leaderboard (reports/tables/leaderboard.py) and ``--against`` (reports/data/against.py).

Aggregates are checked against rliable's own metrics on matrices worked out by hand; the
merge is checked end to end on tiny stores: a run of the new method merged with a run of
the baselines gives exactly the leaderboard of one run that trained every method, and a
run whose settings or scenarios differ is refused naming the first mismatch.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from rliable import metrics as rly_metrics

from bench.design.cells import Cell
from bench.design.grids import Grid
from envs.errors import BenchError
from reports.data.against import merge_against
from reports.data.store import load_store
from reports.tables.leaderboard import (
    _iqm,
    _poi,
    _profile,
    _stratified_band,
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
    assert _iqm(*x.T) == pytest.approx(rly_metrics.aggregate_iqm(x))
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
