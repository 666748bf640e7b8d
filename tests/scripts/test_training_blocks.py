"""scripts/training_blocks.py: each block averages each cell's own block mean (a cell that
trained more episodes weighs no more), the blocks cut at multiples of --block, and the
methods stay apart."""
from __future__ import annotations

import importlib.util
from collections.abc import Iterator
from pathlib import Path

import pytest

from algorithms import registry
from bench.design.grid_files import load_grid_file
from bench.store.run_store import RunStore
from tests.bench.conftest import toy_spec, write_finished_store, write_grid_file
from tests.bench.toy_method import TOY_PATH

_spec = importlib.util.spec_from_file_location(
    "training_blocks", Path(__file__).resolve().parents[2] / "scripts" / "training_blocks.py")
assert _spec is not None and _spec.loader is not None
_module = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_module)
blocks = _module.blocks


@pytest.fixture
def run(tmp_path: Path) -> Iterator[Path]:
    """A finished toy run of two seeds, 8 training episodes each."""
    registry.register("toy", TOY_PATH)
    grid = load_grid_file(write_grid_file(tmp_path / "g.toml", toy_spec(), {"seed": [0, 1]}))
    write_finished_store(tmp_path / "run", grid)
    yield tmp_path / "run"
    registry.unregister("toy")


def test_training_blocks__mean_over_cells_of_each_cells_block_mean(run: Path) -> None:
    store = RunStore(run)
    rows = store.read_train()
    # one cell's last part gone: it now has fewer episodes than the other
    short = rows["cell_id"].iloc[0]
    last_first, last_path = store.train_parts(short)[-1]
    last_path.unlink()
    rows = rows[(rows["cell_id"] != short) | (rows["episode"] < last_first)]

    for block in (4, 8):
        table = blocks(str(run), block)
        assert list(table["block"]) == list(range(0, 8, block)) and set(table["method"]) == {"toy"}
        for first in table["block"]:
            inside = rows[(rows["episode"] >= first) & (rows["episode"] < first + block)]
            per_cell = inside.groupby("cell_id")["success_rate"].mean()
            got = table.loc[table["block"] == first].iloc[0]
            assert got["success_rate"] == pytest.approx(per_cell.mean())
            steps = inside.groupby("cell_id")["steps"].mean()
            assert got["steps"] == pytest.approx(steps.mean())
            assert got["cells"] == len(per_cell)
    # the one-block table weighs the cells alike, not their episodes
    pooled = rows["success_rate"].mean()
    assert blocks(str(run), 8)["success_rate"].iloc[0] != pytest.approx(pooled)


def test_training_blocks__a_folder_without_cells_is_one_line_and_status_2(tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as stop:
        blocks(str(tmp_path), 4)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(tmp_path) in err
