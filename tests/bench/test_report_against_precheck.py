"""``bench report --against`` compares the two runs' cell lists before it reads any row:
a mismatch of settings or configurations is refused from cells.parquet."""
from __future__ import annotations

from pathlib import Path

import pytest

from bench.cli import main
from bench.design.cells import Cell
from bench.design.grids import Grid
from tests.bench.conftest import toy_spec, write_finished_store
from tests.bench.toy_method import TOY_PATH


def _store(tmp: Path, name: str, **kw) -> Path:
    cells = tuple(Cell.make(**{**toy_spec(**kw), "method": TOY_PATH, "seed": s}) for s in range(2))
    write_finished_store(tmp / name, Grid(name, "test", cells))
    return tmp / name


def _no_rows(*args, **kwargs):
    raise AssertionError("a training or evaluation row was read before the cell lists were compared")


@pytest.mark.parametrize("other, message", [
    ({"horizon": 14}, "horizon differs at N=4 p=0.2: 12 here, 14 there"),
    ({"loss_p": 0.4}, "no done cell at N=4 p=0.2"),
])
def test_against__refused_from_the_cell_lists_without_reading_a_row(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], other, message) -> None:
    mine, ref = _store(tmp_path, "mine"), _store(tmp_path, "ref", **other)
    monkeypatch.setattr("bench.store.run_store.RunStore.read_rows", _no_rows)  # the one reader of rows
    with pytest.raises(SystemExit) as exc:
        main(["report", "--run", str(mine), "--against", str(ref), "--out", str(tmp_path / "report")])
    err = capsys.readouterr().err.strip()
    assert exc.value.code == 2 and len(err.splitlines()) == 1 and message in err, err
    assert not (tmp_path / "report").exists()
