"""Which commits trained a run's cells, when some were imported from another run:
``maintenance/import_cells.py`` copied finished cells, and the manifest keeps the run
records of the invocations that trained them (marked ``imported_from``) beside one record of
the import (``cells_imported``). The commit of each cell is the ``git`` of the bench that
finished it (cells.parquet ``versions_json``); a cell whose commit is none of this run's own
invocations' came with the import. A run without an import gets no section (its manifest
table already names its commits)."""
from __future__ import annotations

import json
from collections import Counter
from typing import Any

import pandas as pd


def _git(versions: Any) -> str:
    try:
        return str(json.loads(str(versions)).get("git") or "")
    except (ValueError, AttributeError):
        return ""


def provenance_lines(cells: pd.DataFrame, manifest: dict[str, Any]) -> list[str]:
    """Sentences (plain text) on the commits that trained the imported and the own cells; []
    when the manifest records no import."""
    runs = [r for r in manifest.get("runs") or [] if isinstance(r, dict)]
    imports = [r for r in runs if r.get("cells_imported")]
    if not imports or "versions_json" not in cells:
        return []
    own = sorted({str(r["git"])[:7] for r in runs if r.get("git") and not r.get("imported_from")})
    done = cells[cells["status"] == "done"]
    commits = [_git(v)[:7] for v in done["versions_json"]]
    came = Counter(c for c in commits if c and c not in own)
    stated = sum(int(r["cells_imported"]) for r in imports)
    sources = ", ".join(sorted({str(r.get("imported_from")) for r in imports}))
    ranked = sorted(came.items(), key=lambda kv: (-kv[1], kv[0]))
    listed = ", ".join(f"{c} ({n} cell{'s' if n != 1 else ''})" for c, n in ranked)
    return [
        f"{stated} cells were imported from {sources} by scripts/import_cells.py (the manifest's record with "
        f"cells_imported); they were trained by the runs whose records carry imported_from, not by this run's own "
        f"invocations.",
        f"The bench that finished each imported cell ran at one of {len(came)} commits ({sum(came.values())} cells; "
        f"cells.parquet versions_json): {listed}.",
        f"This run's own invocations ran at {', '.join(own) or 'no recorded commit'} and finished the other "
        f"{len(commits) - sum(came.values())} done cells.",
    ]
