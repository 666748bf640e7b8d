"""The committed state of the full-grid run (reproduction/full, still running across
sessions): every cell belongs to the `full` grid, the cells imported from reproduction/paper
are byte-identical copies of the paper's files, and the manifest says which runs trained
what (the imported runs marked ``imported_from``)."""
from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from bench.design.grids import get_grid

ROOT = Path(__file__).resolve().parents[2] / "reproduction"
FULL, PAPER = ROOT / "full", ROOT / "paper"
pytestmark = pytest.mark.skipif(not (FULL / "cells.parquet").is_file(), reason="no full-grid run committed")


def test_full_run__every_cell_is_a_full_grid_cell_and_no_paper_cell_is_missing() -> None:
    cells = pd.read_parquet(FULL / "cells.parquet")
    grid = {c.cell_id for c in get_grid("full").cells}
    assert set(cells["cell_id"]) <= grid
    paper = pd.read_parquet(PAPER / "cells.parquet")
    in_both = set(paper["cell_id"]) & grid
    done = set(cells.loc[cells["status"] == "done", "cell_id"])
    assert in_both <= done, f"paper cells of the full grid not done here: {sorted(in_both - done)[:3]}"


def test_full_run__imported_cells_are_copies_of_the_paper_files() -> None:
    paper = set(pd.read_parquet(PAPER / "cells.parquet")["cell_id"])
    for path in sorted((FULL / "eval").glob("*.parquet")):
        if path.stem in paper:
            assert path.read_bytes() == (PAPER / "eval" / path.name).read_bytes(), path.name


def test_full_run__manifest_names_the_import_and_the_runs_that_trained_the_cells() -> None:
    runs = json.loads((FULL / "manifest.json").read_text())["runs"]
    imported = [r for r in runs if r.get("imported_from")]
    assert any("cells_imported" in r for r in imported)
    own = [r for r in runs if not r.get("imported_from")]
    assert own and all(r.get("git") and r.get("started") for r in own)
