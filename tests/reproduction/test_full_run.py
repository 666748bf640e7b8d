"""The committed full-grid run (reproduction/full, trained across sessions): every cell
belongs to the `full` grid, the cells imported from reproduction/paper are byte-identical
copies of the paper's files, the manifest says which runs trained what (the imported runs
marked ``imported_from``), and the README's headline prose quotes the committed report."""
from __future__ import annotations

import json
import re
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


# A number with its interval as the report prints it: "64.6% [56.7%, 68.1%]", "+77.2 pp [+52.0, +100.0]".
INTERVAL = re.compile(r"[-+]?\d+\.\d(?:%| pp) \[[-+]?\d+\.\d%?, [-+]?\d+\.\d%?\]")


# Where typed prose quotes the full grid: page, the heading it starts after, the text it ends before.
PROSE = [("README.md", "## Headline result", "<!-- full_ordering:begin -->"),
         ("docs/reproduction.md", "## The full grid", "## Ablation of the hierarchical method")]


@pytest.mark.skipif(not (FULL / "report").is_dir(), reason="the full grid's report is not committed yet")
@pytest.mark.parametrize(("page", "start", "end"), PROSE)
def test_prose__every_interval_quoted_from_the_full_grid_is_printed_by_its_report(page, start, end) -> None:
    """The README's headline findings and the reproduction page's full-grid section are prose
    with typed numbers; each number given with its interval must be one the committed
    full-grid report prints, so a rebuilt report with other numbers fails here until the prose
    is updated."""
    text = (ROOT.parent / page).read_text(encoding="utf-8")
    assert start in text and end in text.split(start, 1)[1], f"{page}: no section from {start!r} to {end!r}"
    section = " ".join(text.split(start, 1)[1].split(end, 1)[0].split())  # intervals wrap across lines
    typed = INTERVAL.findall(section)
    assert typed, f"{page}: the full grid's findings give no number with its interval"
    printed = "\n".join(p.read_text(encoding="utf-8") for p in (FULL / "report").glob("*.md"))
    missing = [t for t in typed if t not in printed]
    assert not missing, f"{page}: numbers not printed by reproduction/full/report: {missing}"
