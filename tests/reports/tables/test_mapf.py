"""The MAPF metrics in the report (issue 53): a lifelong run's report shows throughput and its
leaderboard ranks by it; a store whose eval rows lack the MAPF columns (NaN) reports as before."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bench.design.cells import Cell
from bench.design.grids import Grid
from reports.build import build_report
from reports.data.store import load_store
from reports.data.variants import cell_variants
from reports.tables.leaderboard import leaderboard_display, leaderboard_frame, leaderboard_markdown
from reports.tables.mapf import MAPF_METRICS, mapf_frame
from tests.bench.conftest import toy_spec, write_finished_store
from tests.bench.toy_method import TOY_PATH


def _cells(task: str, delays: tuple[float, ...] = (0.0,)) -> tuple[Cell, ...]:
    out = []
    for method in (TOY_PATH, "pibt"):
        spec = toy_spec(task=task) if method == TOY_PATH else {**toy_spec(task=task), "episodes": 0}
        out += [Cell.make(**{**spec, "method": method, "seed": s, "delay": d}) for s in range(2) for d in delays]
    return tuple(out)


@pytest.fixture(scope="module")
def lifelong(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = tmp_path_factory.mktemp("lifelong") / "run"
    write_finished_store(run, Grid("life", "toy and PIBT, lifelong, delay 0 and 2", _cells("lifelong", (0.0, 2.0))))
    return run


@pytest.fixture(scope="module")
def one_shot(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = tmp_path_factory.mktemp("oneshot") / "run"
    write_finished_store(run, Grid("oneshot", "toy and PIBT, one-shot", _cells("one-shot")))
    return run


def test_lifelong_report__shows_throughput_per_method_and_delay(lifelong: Path) -> None:
    out = build_report(lifelong)
    frame = pd.read_csv(out / "mapf.csv")
    assert set(frame["task"]) == {"lifelong"} and frame["seeds"].eq(2).all()
    assert frame["throughput"].gt(0).any() and frame[["csr", "sum_of_costs", "makespan"]].isna().all().all()
    assert set(frame["variant"].fillna("")) == {"", "delay=2.0"}  # delay 2 is its own row, never pooled
    evals = load_store(lifelong).eval
    pibt = frame[(frame["method"] == "pibt") & frame["variant"].isna()].iloc[0]
    seeds = evals[evals["cell_id"].isin(_default_pibt(lifelong))].groupby("cell_id")["throughput"].mean()
    assert pibt["throughput"] == pytest.approx(seeds.mean())
    assert pibt["throughput_lo"] < pibt["throughput"] < pibt["throughput_hi"] or seeds.nunique() == 1
    assert "### MAPF metrics" in (out / "index.md").read_text(encoding="utf-8")
    assert "throughput (goals/step)" in (out / "index.html").read_text(encoding="utf-8")


def _default_pibt(run: Path) -> list[str]:
    cells = load_store(run).cells
    variants = cell_variants(cells)
    return [c for c in cells.loc[cells["method"] == "pibt", "cell_id"] if variants[c] == ""]


def test_lifelong_leaderboard__ranks_by_throughput(lifelong: Path) -> None:
    out = build_report(lifelong)
    board = pd.read_csv(out / "leaderboard.csv")
    assert len(board) and {"throughput", "throughput_lo", "throughput_hi"} <= set(board.columns)
    for _, g in board.groupby(["n_robots", "loss_p"]):
        planners = g[g["execution"] == "planner"]
        for mode in set(g["execution"]) - {"planner"}:
            both = pd.concat([g[g["execution"] == mode], planners])
            expect = both["throughput"].rank(ascending=False, method="min").astype(int)
            assert both["rank"].tolist() == expect.tolist()
    assert "throughput (goals/step)" in (out / "leaderboard.md").read_text(encoding="utf-8")


def test_one_shot_report__shows_csr_sum_of_costs_and_makespan(one_shot: Path) -> None:
    frame = mapf_frame(load_store(one_shot).eval, load_store(one_shot).cells)
    assert set(frame["task"]) == {"one-shot"} and frame["throughput"].isna().all()
    assert frame[["csr", "sum_of_costs", "makespan"]].notna().all().all()
    assert frame["csr"].between(0, 1).all() and (frame["makespan"] <= frame["sum_of_costs"] + 1e-9).all()


def test_old_store__no_mapf_table_and_the_leaderboard_unchanged(one_shot: Path) -> None:
    store = load_store(one_shot)
    old = store.eval.assign(**{m: np.nan for m in MAPF_METRICS})  # how an older file reads
    assert mapf_frame(old, store.cells).empty
    pre = old.drop(columns=list(MAPF_METRICS))
    board = leaderboard_frame(old)
    pd.testing.assert_frame_equal(board, leaderboard_frame(pre.assign(throughput=np.nan)))
    assert list(board.columns) == ["n_robots", "loss_p", "execution", "method", "label", "seeds", "success",
                                   "success_lo", "success_hi", "success_cov", "correction_rate", "fallback_rate",
                                   "rank"]
    md = leaderboard_markdown(board, pd.DataFrame(), pd.DataFrame(), pd.DataFrame(columns=["method"]))
    assert "throughput" not in md and "throughput" not in leaderboard_display(board).to_string()


def test_lifelong_aggregates_and_figure__throughput(lifelong: Path, one_shot: Path) -> None:
    """A lifelong run's IQM and probability of improvement are over its throughput matrix, and
    its leaderboard's figure is throughput against N; a one-shot run keeps success."""
    from rliable import metrics as rly_metrics

    from reports.data.variants import default_rows
    from reports.tables.leaderboard import score_matrices

    out = build_report(lifelong)
    store = load_store(lifelong)
    evals = default_rows(store.eval, cell_variants(store.cells))
    agg = pd.read_csv(out / "leaderboard_aggregate.csv")
    for mode, g in agg.groupby("execution"):
        mats, _, _ = score_matrices(evals, str(mode), "throughput")
        for r in g.itertuples():
            assert r.iqm == pytest.approx(rly_metrics.aggregate_iqm(mats[r.method]))
    assert agg["iqm"].gt(0).all()
    board = (out / "leaderboard.md").read_text(encoding="utf-8")
    assert "| IQM throughput (goals/step) | seeds' mean IQM [95% CI] |" in board
    assert (out / "throughput_vs_n.png").stat().st_size > 0
    assert "![Leaderboard: every method of the run](throughput_vs_n.png)" in (out / "index.md").read_text()
    assert "Throughput (goals/step) against team size N" in (out / "throughput_vs_n.txt").read_text()
    # every score surface of a lifelong run is throughput's (docs/decisions/0235)
    assert not (out / "success_vs_n.png").exists() and (out / "throughput_vs_p.png").stat().st_size > 0
    assert "runs with throughput above tau" in (out / "performance_profiles.txt").read_text()
    assert "highest mean throughput" in (out / "leaders.md").read_text(encoding="utf-8")
    assert (out / "success_by_mode.md").read_text(encoding="utf-8").count("Throughput (goals reached per step") == 1
    plain = build_report(one_shot)
    assert not (plain / "throughput_vs_n.png").exists()
    assert "![Leaderboard: every method of the run](success_vs_n.png)" in (plain / "index.md").read_text()
    assert "| IQM success | seeds' mean IQM [95% CI] |" in (plain / "leaderboard.md").read_text(encoding="utf-8")
