"""Named presets (``preset = "tuned"``): a method declares them, a grid file selects them,
the cell records the name and the values, and ``paper`` leaves every existing cell id as it was."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from algorithms.presets import Preset
from bench.design.cells import Cell
from bench.design.grid_files import load_grid_file
from envs.errors import BenchError
from tests.bench.toy_method import ToyMethod

REPO = Path(__file__).resolve().parents[3]
STORES = sorted(p for p in (REPO / "reproduction").glob("*/cells.parquet"))


class PresetToy(ToyMethod):
    """The toy method with a published preset and an unpublished one."""

    name = "preset_toy"
    presets = {"tuned": Preset({"lr": 0.5, "search_radius": 3}, source="a test study"),
               "later": Preset.unpublished("studies/definitions/nothing.toml")}


TOY = f"{__name__}:PresetToy"


def cell(**fields: object) -> Cell:
    return Cell.make(method=TOY, n_robots=4, loss_p=0.2, layout="tiny", **fields)


@pytest.mark.parametrize("store", STORES, ids=[p.parent.name for p in STORES])
def test_every_committed_cell_keeps_its_id(store: Path) -> None:
    """The paper preset is the default and is not recorded: every committed cell rebuilds
    from its config JSON to the id it was stored under, and only a cell its grid file
    (``reproduction/<store>.toml``) selects with a preset records one."""
    cells = pd.read_parquet(store, columns=["cell_id", "config_json"])
    assert len(cells) > 0
    grid_file = store.parent.with_suffix(".toml")
    selected = {c.cell_id: c.preset for c in load_grid_file(grid_file).cells} if grid_file.exists() else {}
    for row in cells.itertuples():
        rebuilt = Cell.from_json(row.config_json)
        assert rebuilt.preset == selected.get(row.cell_id, "paper")
        assert rebuilt.cell_id == row.cell_id
        assert rebuilt.canonical_json() == row.config_json


def test_paper_preset_spelled_out_is_the_default_cell() -> None:
    assert cell(preset="paper").cell_id == cell().cell_id
    assert "preset" not in json.loads(cell().canonical_json())


def test_tuned_preset_fills_unset_values_and_is_recorded() -> None:
    tuned = cell(preset="tuned")
    assert tuned.params == {"lr": 0.5}
    assert tuned.search_radius == 3
    assert tuned.method_params().lr == 0.5  # type: ignore[attr-defined]
    assert json.loads(tuned.canonical_json())["preset"] == "tuned"
    # the same values without the name are another cell (the id records the preset's name)
    assert tuned.cell_id != cell(search_radius=3, params={"lr": 0.5}).cell_id
    assert tuned.cell_id != cell().cell_id
    # rebuilt from what the store keeps, the cell is the same
    assert Cell.from_json(tuned.canonical_json()).cell_id == tuned.cell_id


def test_explicit_values_win_over_the_preset() -> None:
    mixed = cell(preset="tuned", search_radius=1, params={"lr": 0.1})
    assert mixed.search_radius == 1 and mixed.params == {"lr": 0.1}


def test_missing_and_unpublished_presets_are_one_clear_error() -> None:
    with pytest.raises(BenchError, match=r"preset: method '.*PresetToy' has no preset 'best' "
                                         r"\(its presets: paper, later \(no published study yet\), tuned\)"):
        cell(preset="best")
    with pytest.raises(BenchError, match="no published study for preset 'later' yet .*nothing.toml"):
        cell(preset="later")


def test_a_grid_file_selects_presets_in_base_and_as_an_axis(tmp_path: Path) -> None:
    grid = tmp_path / "g.toml"
    grid.write_text(f'[base]\nmethod = "{TOY}"\nn_robots = 4\nloss_p = 0.2\nlayout = "tiny"\n'
                    '[axes]\npreset = ["paper", "tuned"]\n')
    paper, tuned = load_grid_file(grid).cells
    assert (paper.preset, tuned.preset) == ("paper", "tuned")
    assert paper.cell_id == cell().cell_id and tuned.cell_id == cell(preset="tuned").cell_id
    grid.write_text(f'[base]\nmethod = "{TOY}"\nn_robots = 4\nloss_p = 0.2\nlayout = "tiny"\npreset = "tuned"\n')
    assert load_grid_file(grid).cells[0].cell_id == tuned.cell_id


def test_bench_grids_reports_a_missing_preset_on_one_line_with_status_2(tmp_path: Path) -> None:
    grid = tmp_path / "g.toml"
    grid.write_text('[base]\nmethod = "decentralized"\nn_robots = 8\nloss_p = 0.2\npreset = "best"\n')
    bench = Path(sys.executable).with_name("bench")
    res = subprocess.run([str(bench), "grids", "--grid-file", str(grid)], capture_output=True, text=True,
                         cwd=tmp_path, timeout=120)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "preset" in lines[0] and "g.toml" in lines[0], res.stderr
