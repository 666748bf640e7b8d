"""``bench run --repair`` on an embedded 2-CPU Ray for the damage round four added (D12 a file
where eval/ belongs, D18 a link to an edited copy, D22 a deleted checksums.json): the link
or file itself moves to superseded/repair-<time>/ (its target is never touched), the cells
are recomputed with the same numbers, and the run is verifiable again."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest

from bench.design.cells import Cell
from bench.design.grids import Grid
from bench.execute.runner import run_grid
from bench.store.integrity import CHECKSUMS_FILE, find_damage
from bench.store.run_store import RunStore
from tests.bench.conftest import toy_spec
from tests.bench.store.test_integrity_round4 import edited_copy

pytestmark = [pytest.mark.slow, pytest.mark.usefixtures("ray_local")]


def _evals(out: Path) -> pd.DataFrame:
    return RunStore(out).read_eval().sort_values(["cell_id", "execution", "episode"]).reset_index(drop=True)


@pytest.mark.parametrize("damage", ["link", "file_for_eval_folder", "checksums_deleted"])
def test_repair__recomputes_what_the_link_file_or_lost_checksums_hid(toy: str, tmp_path: Path, damage: str) -> None:
    grid = Grid("toygrid", "test", tuple(Cell.make(**toy_spec(seed=s)) for s in (0, 1)))
    a, b = (cell.cell_id for cell in grid.cells)
    out = tmp_path / "run"
    assert run_grid(grid, out, workers=2, checkpoint_every=1).done == 2
    eval0 = _evals(out)
    outside = tmp_path / "edited.parquet"
    if damage == "link":
        edited_copy(out / "eval" / f"{b}.parquet", outside)
        (out / "eval" / f"{b}.parquet").unlink()
        (out / "eval" / f"{b}.parquet").symlink_to(outside)
    elif damage == "file_for_eval_folder":
        shutil.rmtree(out / "eval")
        (out / "eval").write_text("not a folder\n")
    else:
        edited_copy(out / "eval" / f"{b}.parquet", out / "eval" / f"{b}.parquet")
        (out / CHECKSUMS_FILE).unlink()
    s = run_grid(grid, out, workers=2, checkpoint_every=1, repair=True)
    assert s.done == 2 and s.repaired
    pd.testing.assert_frame_equal(_evals(out), eval0)
    assert find_damage(RunStore(out), RunStore(out).integrity()) == []
    moved = {m["file"] for f in (out / "superseded").glob("repair-*/repair.json") for m in json.loads(f.read_text())}
    if damage == "link":
        assert moved == {f"eval/{b}.parquet"} and outside.is_file()  # the target is left alone
    elif damage == "file_for_eval_folder":
        assert moved == {"eval"}
    else:
        assert f"eval/{b}.parquet" in moved and "cells.parquet" in moved
