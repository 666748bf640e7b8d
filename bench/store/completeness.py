"""How many rows a done cell must have, and whether the store holds them (SPEC 7).

A cell counts as done only when its stored rows are complete: ``bench run`` re-runs a done
cell whose rows fall short (bench/execute/plan.py), and ``bench report`` warns naming it. The
expected counts come from the cell config alone, in ONE function, ``expected_rows``:

* training: a learned method runs ceil(episodes / batch_episodes) updates of
  batch_episodes episodes and keeps every row (docs/results-schema.md); a planner (PIBT,
  ``learned = False``) or ``episodes = 0`` has none;
* evaluation: ``eval_episodes`` rows per execution mode the cell is evaluated in
  (``Cell.execution_modes()``: argmax, sample, sample@T for a learned method; planner for
  PIBT), i.e. ``eval_episodes x n_modes``, and each (mode, episode) pair exactly once.

``cell_rows`` is the one rule that decides whether a done cell's rows are complete; the
runner (bench/execute/plan.py, from the cell config) and the report (reports/data/store.py,
through ``incomplete_cells``, from the cells.parquet row) both ask it, so they agree on
every damage: a missing training part, a missing mode or episode, a duplicated row, a row
of another mode, an unreadable file. Training counts are read from the Parquet footers;
the evaluation file's (execution, episode) columns are read to check the pairs.
"""
from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import pyarrow.parquet as pq

from algorithms.common.execution import PLANNER
from bench.store.run_store import RunStore, read_table
from bench.store.schema import EVAL_SCHEMA
from envs.errors import BenchError

__all__ = ["CellRows", "RowCounts", "cell_rows", "expected_for_cell", "expected_for_row", "expected_rows",
           "incomplete_cells", "modes_of_row", "row_cell_rows", "shortfall", "stored_rows"]


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
    modes = modes_of_row(row)
    learned = PLANNER not in modes
    return expected_rows(learned, int(row["episodes"]), int(row["eval_episodes"]), params, len(modes))


def modes_of_row(row: Mapping[str, Any]) -> list[str]:
    """The execution modes a cells.parquet row was evaluated in (``executions``)."""
    modes = [m for m in str(row.get("executions") or "").split(",") if m]
    if not modes:
        raise ValueError("no executions recorded")
    return modes


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


@dataclass(frozen=True)
class CellRows:
    """What a done cell's store holds against what it must: row counts, and the
    evaluation pairs that are missing (per mode), duplicated or of another mode/episode."""

    expected: RowCounts
    stored: RowCounts
    missing: tuple[tuple[str, int], ...] = ()  # (mode, episodes present) for each short mode
    duplicated: int = 0
    foreign: int = 0
    eval_episodes: int = 0
    eval_file: bool = True  # whether the cell's eval file exists at all

    @property
    def train_complete(self) -> bool:
        return self.stored.train == self.expected.train

    @property
    def gap(self) -> str:
        """'' when complete, else what is wrong, e.g. '0 of 5 evaluation episodes in
        execution mode sample@0.5' or '32 of 40 training rows'."""
        parts = [] if self.train_complete else [f"{self.stored.train} of {self.expected.train} training rows"]
        if self.expected.eval and not self.stored.eval:
            parts.append("no evaluation rows")
        else:
            parts += [f"{n} of {self.eval_episodes} evaluation episodes in execution mode {m}" for m, n in self.missing]
            if self.duplicated:
                parts.append(f"{self.duplicated} duplicated evaluation rows")
            if self.foreign:
                parts.append(f"{self.foreign} evaluation rows of another execution mode or episode")
        return ", ".join(parts)


def cell_rows(store: RunStore, cell_id: str, expected: RowCounts, modes: Sequence[str],
              eval_episodes: int) -> CellRows:
    """The one completeness rule (see the module docstring): the cell's stored rows against
    ``expected`` and every (mode, episode) of ``modes`` x ``range(eval_episodes)`` once.
    A corrupt file is a ``BenchError``."""
    stored = stored_rows(store, cell_id)
    path = store.eval_path(cell_id)
    pairs: Counter[tuple[str, int]] = Counter()
    if path.exists():
        df = read_table(path, EVAL_SCHEMA).select(["execution", "episode"]).to_pandas()
        pairs = Counter(zip(df["execution"].astype(str), df["episode"].astype(int), strict=True))
    want = {(m, e) for m in modes for e in range(eval_episodes)}
    missing = tuple((m, sum((m, e) in pairs for e in range(eval_episodes))) for m in modes
                    if any((m, e) not in pairs for e in range(eval_episodes)))
    return CellRows(expected, stored, missing, sum(k - 1 for k in pairs.values() if k > 1),
                    sum(k for pair, k in pairs.items() if pair not in want), eval_episodes, path.exists())


def row_cell_rows(store: RunStore, row: Mapping[str, Any]) -> CellRows:
    """``cell_rows`` of a cells.parquet row (its expected rows from ``expected_for_row``).
    An unknown method or odd row is a ``ValueError``/``KeyError``/``ImportError``; a corrupt
    file a ``BenchError``."""
    return cell_rows(store, str(row["cell_id"]), expected_for_row(row), modes_of_row(row), int(row["eval_episodes"]))


def incomplete_cells(store: RunStore, cells: Any) -> dict[str, str]:
    """{cell_id: what is wrong} of the done cells (cells.parquet frame) whose rows are
    incomplete (``cell_rows``)."""
    out = {}
    for row in cells[cells["status"] == "done"].to_dict("records"):
        cid = str(row["cell_id"])
        try:
            expected_for_row(row), modes_of_row(row)
        except (ImportError, KeyError, ValueError) as exc:  # unknown method or odd row: say so
            out[cid] = f"cannot tell the expected rows ({exc})"
            continue
        try:
            gap = row_cell_rows(store, row).gap
        except BenchError as exc:  # an unreadable part: the cell cannot be complete
            gap = str(exc)
        if gap:
            out[cid] = gap
    return out
