"""The committed reproduction runs (issue 13): what is in git is what the current code means.

``reproduction/paper`` is the ``paper`` grid being run part-way across sessions, and
``reproduction/ablation`` the ``ablation`` grid. Every cell they hold must still be a cell of
today's grid definition (same cell_id: a changed default or setting would silently orphan the
committed rows), every done cell must have all its rows (training rows, and evaluation rows in
every execution mode, episode by episode), and a cell that is not done must have its
checkpoint committed so that a fresh clone resumes it. When the paper grid is complete this
module also gets the claims-page rebuild check of issue 13.
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from bench.completeness import incomplete_cells
from bench.grids import BUILTIN, DEFAULT_SEEDS
from bench.store import RunStore

ROOT = Path(__file__).resolve().parents[2] / "reproduction"
RUNS = [name for name in ("paper", "ablation") if (ROOT / name / "cells.parquet").is_file()]


@pytest.fixture(params=RUNS)
def run(request: pytest.FixtureRequest) -> tuple[str, RunStore, pd.DataFrame]:
    store = RunStore(ROOT / request.param)
    return request.param, store, store.read_cells()


def test_reproduction__the_paper_run_is_committed() -> None:
    assert "paper" in RUNS, "reproduction/paper/cells.parquet is missing"


def test_committed_cells__are_cells_of_todays_grid(run) -> None:
    name, _, cells = run
    grid = BUILTIN[name](seeds=DEFAULT_SEEDS[name])
    unknown = set(cells["cell_id"]) - {c.cell_id for c in grid.cells}
    assert not unknown, f"reproduction/{name}: cells no longer in the {name} grid: {sorted(unknown)}"


def test_committed_done_cells__have_every_row_in_every_mode(run) -> None:
    name, store, cells = run
    assert (cells["status"] != "failed").all(), f"reproduction/{name}: failed cells committed"
    assert incomplete_cells(store, cells) == {}
    done = cells[cells["status"] == "done"]
    ev = store.read_eval()
    for row in done.itertuples():
        per_mode = ev[ev["cell_id"] == row.cell_id].groupby("execution")["episode"].apply(set).to_dict()
        want = {mode: set(range(row.eval_episodes)) for mode in row.executions.split(",")}
        assert per_mode == want, f"reproduction/{name}: {row.cell_id} ({row.method}) eval rows per mode"


def test_committed_unfinished_cells__can_resume_from_a_committed_checkpoint(run) -> None:
    name, store, cells = run
    started = cells[(cells["status"] != "done") & (cells["train_episodes_done"] > 0)]
    for cid in started["cell_id"]:
        assert (store.root / "checkpoints" / f"{cid}.pt").is_file(), f"reproduction/{name}: {cid} has no checkpoint"
