"""reports/pages/provenance.py: a run with imported cells says which commits
trained them; a run without an import gets no section."""
from __future__ import annotations

import json

import pandas as pd

from reports.pages.provenance import provenance_lines


def _cells(gits: list[str]) -> pd.DataFrame:
    return pd.DataFrame({"status": ["done"] * len(gits),
                         "versions_json": [json.dumps({"git": g}) for g in gits]})


def test_provenance__names_the_commits_of_the_imported_cells_and_of_the_own_ones() -> None:
    manifest = {"runs": [{"git": "aaaaaaa1", "imported_from": "paper"}, {"git": "bbbbbbb2", "imported_from": "paper"},
                         {"imported_from": "paper", "cells_imported": 3}, {"git": "ccccccc3"}]}
    lines = provenance_lines(_cells(["aaaaaaa1", "aaaaaaa1", "bbbbbbb2", "ccccccc3"]), manifest)
    assert lines[0].startswith("3 cells were imported from paper")
    assert "one of 2 commits (3 cells" in lines[1] and "aaaaaaa (2 cells), bbbbbbb (1 cell)" in lines[1]
    assert "ran at ccccccc and finished the other 1 done cells" in lines[2]


def test_provenance__a_run_without_an_import_has_none() -> None:
    assert provenance_lines(_cells(["aaaaaaa1", "bbbbbbb2"]), {"runs": [{"git": "aaaaaaa1"}]}) == []
