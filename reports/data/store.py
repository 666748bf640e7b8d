"""Read a run's Parquet store (docs/results-schema.md) into the frames the builders use.

The report is rebuilt from the store alone: ``cells.parquet`` (one row per cell),
``train/`` and ``eval/`` (Parquet datasets, one row per cell and episode) and
``manifest.json``, read with the bench's one reader of row datasets
(``bench.store.run_store.RunStore.read_rows``: schema version checked per file, damaged
files skipped and listed). Per-episode rows are joined with the configuration columns of their
cell (method, n_robots, loss_p, seed, groups, ...). Evaluation rows carry their execution
mode (``execution``: argmax, sample, sample@T, or planner), one row per cell x episode x
mode; a done cell missing a mode or an episode is listed in ``Store.problems``. Only cells whose status is ``done``
feed figures, tables and claims; the others are listed as missing (docs/decisions/0033).
A store without a ``train/`` or ``eval/`` dataset still loads (empty frames).
"""
from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from bench.execute.plan import dict_changes
from bench.store.completeness import incomplete_cells
from bench.store.integrity import REPAIR_FILE, REPAIR_PREFIX, Damage
from bench.store.run_store import RunStore
from bench.store.schema import EVAL_SCHEMA, TRAIN_SCHEMA
from envs.errors import BenchError

__all__ = ["CONFIG_COLUMNS", "Store", "execution_order", "fmt_p", "fmt_pct", "load_store", "select",
           "superseded_notes"]

# The cell config columns joined onto every train and eval row.
CONFIG_COLUMNS = ("method", "n_robots", "loss_p", "seed", "groups", "safety_filter")


@dataclass
class Store:
    """A run's data: ``cells`` (all cells), ``train``/``eval`` (rows of done cells, with
    their cell's config columns), the manifest, and what the store lacks."""

    run_dir: Path
    cells: pd.DataFrame
    train: pd.DataFrame
    eval: pd.DataFrame
    manifest: dict[str, Any] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)  # unreadable or absent parts

    @property
    def done(self) -> pd.DataFrame:
        return self.cells[self.cells["status"] == "done"]

    @property
    def not_done(self) -> pd.DataFrame:
        return self.cells[self.cells["status"] != "done"]


def _with_config(rows: pd.DataFrame, done: pd.DataFrame) -> pd.DataFrame:
    cfg = done[["cell_id", *CONFIG_COLUMNS]]
    out = rows.merge(cfg, on="cell_id", how="inner")
    key = ["cell_id", "execution", "episode"] if "execution" in out else ["cell_id", "episode"]
    return out.drop_duplicates(key, keep="last").sort_values(key, kind="stable").reset_index(drop=True)


def execution_order(modes: Iterable[object]) -> list[str]:
    """Execution modes in report order: argmax, sample, sample@T by decreasing T, planner."""
    def key(m: str) -> tuple[int, float]:
        if m == "argmax":
            return (0, 0.0)
        if m == "sample":
            return (1, 0.0)
        if m.startswith("sample@"):
            try:
                return (2, -float(m.split("@", 1)[1]))
            except ValueError:
                return (3, 0.0)
        return (4, 0.0)
    return sorted({str(m) for m in modes}, key=lambda m: (*key(m), m))


def load_store(run_dir: Path | str) -> Store:
    """Read the store under ``run_dir``. No ``cells.parquet``, or a store of another schema
    version, is a ``BenchError``; anything else missing is listed in ``Store.problems``."""
    run = Path(run_dir)
    rs = RunStore(run)
    manifest: dict[str, Any] = {}
    manifest_problems: list[str] = []
    checksums = None
    try:
        manifest = rs.read_manifest() or {}
        if not manifest:
            manifest_problems.append("manifest.json is absent")
        checksums = rs.integrity()
    except BenchError as exc:
        manifest_problems.append(str(exc))
    why = checksums.mismatch(rs.cells_path) if checksums is not None and rs.cells_path.is_file() else ""
    if why:
        raise BenchError(f"{str(run)!r}: {Damage('cells.parquet', '', why).line()}")
    try:
        cells = rs.read_cells()
    except BenchError as exc:
        if "corrupt Parquet" not in str(exc):
            raise
        raise BenchError(f"{str(run)!r}: {Damage('cells.parquet', '', 'unreadable Parquet').line()}") from None
    if cells is None:
        raise BenchError(f"no results store at {str(run)!r}: cells.parquet not found "
                         "(run `bench run` first, or pass --run DIR)")
    cells["status"] = cells["status"].fillna("pending").astype(str)
    cells["error"] = cells["error"].fillna("").astype(str)
    cells["safety_filter"] = cells["safety_filter"].fillna(False).astype(bool)
    problems: list[str] = []
    done = cells[cells["status"] == "done"]
    damaged: set[str] = set()
    train = _with_config(rs.read_rows(rs.train_dir, TRAIN_SCHEMA, problems, checksums, damaged).to_pandas(), done)
    evals = _with_config(rs.read_rows(rs.eval_dir, EVAL_SCHEMA, problems, checksums, damaged).to_pandas(), done)
    problems += manifest_problems
    if damaged:  # a done cell with a damaged file is not done until `bench run --repair`
        cells.loc[cells["cell_id"].isin(damaged) & (cells["status"] == "done"), "status"] = "pending"
        done = cells[cells["status"] == "done"]
        train, evals = (df[df["cell_id"].isin(done["cell_id"])].reset_index(drop=True) for df in (train, evals))
    problems += [f"cell {cid} is done but its rows are incomplete: {gap}"  # the runner's rule
                 for cid, gap in incomplete_cells(rs, done).items()]
    problems += superseded_notes(run, cells)
    return Store(run, cells.reset_index(drop=True), train, evals, manifest, problems)


def superseded_notes(run: Path, cells: pd.DataFrame) -> list[str]:
    """One line per folder of ``superseded/`` (a cell trained again because its method
    parameters changed, ``bench run --rerun-changed``): which cell, what changed. Its
    former rows stay there and are not shown."""
    root = run / "superseded"
    if not root.is_dir():
        return []
    now = dict(zip(cells["cell_id"].astype(str), cells["params_json"].astype(str), strict=True))
    out = []
    for d in sorted(p for p in root.iterdir() if p.is_dir()):
        if d.name.startswith(REPAIR_PREFIX):  # bench run / matrix --repair (bench/store/integrity.py)
            try:
                moved = json.loads((d / REPAIR_FILE).read_text())
                files = ", ".join(f"{m['file']} ({m['why']})" for m in moved)
            except (OSError, ValueError, TypeError, KeyError):
                files = f"unreadable {REPAIR_FILE}"
            out.append(f"superseded/{d.name}: damaged files moved aside by --repair and recomputed: {files}")
            continue
        try:
            row = json.loads((d / "cells_row.json").read_text())
            changed = dict_changes(json.loads(row.get("params_json") or "{}"),
                                   json.loads(now.get(str(row.get("cell_id")), "{}")))
        except (OSError, ValueError, AttributeError, TypeError):
            out.append(f"superseded/{d.name}: unreadable cells_row.json")
            continue
        out.append(f"superseded/{d.name}: {row.get('method')} N={row.get('n_robots')} p={row.get('loss_p')} "
                   f"seed={row.get('seed')} was trained again with other parameters "
                   f"({'; '.join(changed) or 'unchanged'}); its former rows are kept there, not shown")
    return out


def select(df: pd.DataFrame, method: str | None = None, n_robots: int | None = None,
           loss_p: float | None = None) -> pd.DataFrame:
    """Rows of ``df`` matching the given method, team size and loss probability."""
    m = np.ones(len(df), dtype=bool)
    if method is not None:
        m &= (df["method"] == method).to_numpy()
    if n_robots is not None:
        m &= (df["n_robots"] == n_robots).to_numpy()
    if loss_p is not None:
        m &= np.isclose(df["loss_p"].to_numpy(dtype=np.float64), loss_p)
    return df[m]


def fmt_p(p: float) -> str:
    """Loss probability as written in the paper (0.2, 0.4, ...)."""
    return f"{float(p):g}"


def fmt_pct(fraction: float, decimals: int, always_sig: bool = False) -> str:
    """A fraction in percent (without the % sign) with ``decimals`` decimals, or with three
    significant digits when it is nonzero and the decimals would show it as zero (always,
    with ``always_sig``): a collision rate of 0.0008% must never print as 0.00%."""
    pct = 100 * float(fraction)
    if pct != 0 and np.isfinite(pct) and (always_sig or abs(pct) < 0.5 * 10.0 ** -decimals):
        return np.format_float_positional(pct, precision=3, fractional=False, trim="-")
    return f"{pct:.{decimals}f}"
