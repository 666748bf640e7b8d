"""How many rows a done cell must have, and whether the store holds them (SPEC 7).

A cell counts as done only when its stored rows are complete: ``bench run`` re-runs a done
cell whose rows fall short (bench/execute/plan.py), and ``bench report`` warns naming it. The
expected counts come from the cell config alone, in ONE function, ``expected_rows``:

* training: a learned method runs ceil(episodes / batch_episodes) updates of
  batch_episodes episodes and keeps every row (docs/results-schema.md); a planner (PIBT,
  ``learned = False``) or ``episodes = 0`` has none;
* evaluation: ``eval_episodes`` rows per execution mode the cell is evaluated in
  (``Cell.execution_modes()``: argmax, sample, sample@T for a learned method; planner for
  PIBT), i.e. ``eval_episodes x n_modes``. bench/execute/plan.py ``eval_complete`` additionally
  checks that every (mode, episode) pair is present.

Stored counts are read from the Parquet footers (no row data is loaded).
"""
from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import pyarrow.parquet as pq

from algorithms.common.execution import PLANNER
from bench.store.run_store import RunStore
from envs.errors import BenchError

__all__ = ["RowCounts", "expected_for_cell", "expected_for_row", "expected_rows", "incomplete_cells", "shortfall",
           "stored_rows"]


@dataclass(frozen=True)
class RowCounts:
    train: int
    eval: int


def expected_rows(learned: bool, episodes: int, eval_episodes: int, params: Mapping[str, Any],
                  n_modes: int) -> RowCounts:
    """Rows a done cell of this config has in train/ and eval/ (the single source of truth);
    ``learned``: the method's trait (a planner has no training rows); ``n_modes``: how many
    execution modes it is evaluated in."""
    batch = max(int(params.get("batch_episodes", 1)), 1)
    train = math.ceil(episodes / batch) * batch if learned and episodes > 0 else 0
    return RowCounts(train, int(eval_episodes) * int(n_modes))


def expected_for_cell(cell: Any) -> RowCounts:
    """``expected_rows`` of a ``bench.design.cells.Cell``."""
    params = cell.method_params().model_dump(mode="json")
    from algorithms.registry import method_class

    return expected_rows(method_class(cell.method).learned, cell.episodes, cell.eval_episodes, params,
                         len(cell.execution_modes()))


def expected_for_row(row: Mapping[str, Any]) -> RowCounts:
    """``expected_rows`` of a cells.parquet row (``params_json``: the resolved params;
    ``executions``: its comma-separated evaluation modes; a planner's is ``planner``), so a
    report needs no import of the method: a run of a plugin that is not installed here
    still checks)."""
    params = json.loads(str(row.get("params_json") or "{}"))
    modes = [m for m in str(row.get("executions") or "").split(",") if m]
    if not modes:
        raise ValueError("no executions recorded")
    learned = PLANNER not in modes
    return expected_rows(learned, int(row["episodes"]), int(row["eval_episodes"]), params, len(modes))


def _num_rows(path: Any) -> int:
    try:
        return int(pq.read_metadata(path).num_rows)
    except (OSError, ValueError) as exc:
        raise BenchError(f"corrupt Parquet file {str(path)!r}: {' '.join(str(exc).split())[:200]}") from None


def stored_rows(store: RunStore, cell_id: str) -> RowCounts:
    """Rows of the cell in the store: training parts and the eval file (footers only)."""
    train = sum(_num_rows(p) for _, p in store.train_parts(cell_id))
    path = store.eval_path(cell_id)
    return RowCounts(train, _num_rows(path) if path.exists() else 0)


def shortfall(expected: RowCounts, stored: RowCounts) -> str:
    """'' when complete, else e.g. '32 of 40 training rows' (and/or evaluation rows)."""
    parts = []
    if stored.train != expected.train:
        parts.append(f"{stored.train} of {expected.train} training rows")
    if stored.eval != expected.eval:
        parts.append(f"{stored.eval} of {expected.eval} evaluation rows")
    return ", ".join(parts)


def incomplete_cells(store: RunStore, cells: Any) -> dict[str, str]:
    """{cell_id: shortfall} of the done cells (cells.parquet frame) whose rows are incomplete."""
    out = {}
    for row in cells[cells["status"] == "done"].to_dict("records"):
        try:
            expected = expected_for_row(row)
        except (ImportError, KeyError, ValueError) as exc:  # unknown method or odd row: say so
            out[str(row["cell_id"])] = f"cannot tell the expected rows ({exc})"
            continue
        try:
            gap = shortfall(expected, stored_rows(store, str(row["cell_id"])))
        except BenchError as exc:  # an unreadable part: the cell cannot be complete
            gap = str(exc)
        if gap:
            out[str(row["cell_id"])] = gap
    return out
