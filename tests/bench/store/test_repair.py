"""``bench run --repair`` on an embedded 2-CPU Ray (D2/D3/D11): a flipped bit in a
stored Parquet file or a swapped eval file is moved to superseded/repair-<time>/ and only
its cell is recomputed, with the same numbers; every other stored file stays byte for byte."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest

from bench.design.cells import Cell
from bench.design.grids import Grid
from bench.execute.runner import run_grid
from bench.store.run_store import RunStore
from envs.errors import BenchError
from tests.bench.conftest import snapshot, toy_spec

pytestmark = pytest.mark.usefixtures("ray_local")


def _rows(out: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    store = RunStore(out)
    train = store.read_train().drop(columns="wall_s").sort_values(["cell_id", "episode"]).reset_index(drop=True)
    evals = store.read_eval().sort_values(["cell_id", "execution", "episode"]).reset_index(drop=True)
    return train, evals


def _flip(path: Path) -> None:
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x04
    path.write_bytes(bytes(data))


def _repaired_files(out: Path) -> set[str]:
    return {m["file"] for f in (out / "superseded").glob("repair-*/repair.json") for m in json.loads(f.read_text())}


def test_repair__bit_rot_and_a_swapped_eval_file_recompute_only_their_cells(toy: str, tmp_path: Path) -> None:
    grid = Grid("toygrid", "test", tuple(Cell.make(**toy_spec(seed=s)) for s in (0, 1, 2)))
    a, b, c = (cell.cell_id for cell in grid.cells)
    out = tmp_path / "run"
    assert run_grid(grid, out, workers=2, checkpoint_every=1).done == 3
    train0, eval0 = _rows(out)

    # a flipped bit in a's eval file and in one of b's training parts
    _flip(out / "eval" / f"{a}.parquet")
    part_b = sorted((out / "train" / b).glob("part-*.parquet"))[1]
    _flip(part_b)
    untouched = {k: v for k, v in snapshot(out).items() if k.startswith(("train", "eval", "checkpoints"))
                 and a not in k and b not in k}
    with pytest.raises(BenchError, match="damaged file .*--repair"):
        run_grid(grid, out, workers=2, checkpoint_every=1)
    s = run_grid(grid, out, workers=2, checkpoint_every=1, repair=True)
    assert s.done == 3 and len(s.repaired) == 2
    assert _repaired_files(out) == {f"eval/{a}.parquet", f"train/{b}/{part_b.name}"}
    train1, eval1 = _rows(out)
    pd.testing.assert_frame_equal(train1, train0)
    pd.testing.assert_frame_equal(eval1, eval0)
    after = {k: v for k, v in snapshot(out).items() if k in untouched}
    assert after == untouched  # c was not recomputed: its files are byte for byte the same
    cells = RunStore(out).read_cells().set_index("cell_id")
    assert cells.loc[c, "attempts"] == 1 and cells.loc[a, "attempts"] == 2

    # a swapped pair of eval files: both cells evaluated again from their final checkpoints
    ea, ec = out / "eval" / f"{a}.parquet", out / "eval" / f"{c}.parquet"
    tmp = tmp_path / "x.parquet"
    shutil.move(ea, tmp)
    shutil.move(ec, ea)
    shutil.move(tmp, ec)
    train_b = {k: v for k, v in snapshot(out).items() if k.startswith(("train", f"eval/{b}"))}
    s = run_grid(grid, out, workers=2, checkpoint_every=1, repair=True)
    assert s.done == 3 and len(s.repaired) == 2
    train2, eval2 = _rows(out)
    pd.testing.assert_frame_equal(eval2, eval0)
    assert {k: v for k, v in snapshot(out).items() if k in train_b} == train_b  # no training ran
    # and the report says what was repaired
    from reports.data.store import load_store

    assert sum("moved aside by --repair" in p for p in load_store(out).problems) == 2
