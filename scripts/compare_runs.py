"""Check that two run folders hold the same training and evaluation rows, bit for bit.

    .venv/bin/python scripts/compare_runs.py results/ci-smoke results/docker-check/container/smoke \
        --names host container

Used by ``make docker-check`` (a smoke grid in the container against the same grid on the
host) and the cluster test (a grid on three netns hosts against one machine). Compares the
Parquet rows of ``train/`` and ``eval/``, not file bytes: rows are sorted by cell, execution
mode and episode, the columns that measure the machine (``wall_s``, ``peak_mem_mb``) are
dropped, and every float is compared by its IEEE-754 bits (NaN only equals the same NaN).
Exit status 0 when equal, 1 on the first difference (named), 2 on a missing run folder.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

MACHINE_COLUMNS = ("wall_s", "peak_mem_mb")
"""Columns that measure the machine, not the computation: differ between any two runs."""
KEYS = ("cell_id", "execution", "episode")


def load_rows(run: Path, table: str) -> pd.DataFrame:
    """The rows of ``run/table`` (``train`` or ``eval``) in a canonical order, machine columns dropped."""
    folder = run / table
    if not folder.is_dir() or not any(folder.rglob("*.parquet")):
        return pd.DataFrame()
    frame = pd.read_parquet(folder)
    frame = frame.drop(columns=[c for c in MACHINE_COLUMNS if c in frame.columns])
    keys = [k for k in KEYS if k in frame.columns]
    frame = frame.sort_values(keys, kind="stable").reset_index(drop=True)
    return frame[sorted(frame.columns)]


def _missing(v: object) -> bool:
    return v is None or (isinstance(v, float) and np.isnan(v))


def first_difference(a: pd.DataFrame, b: pd.DataFrame) -> str | None:
    """None when ``a`` and ``b`` hold the same rows bit for bit, else a line naming the first difference."""
    if list(a.columns) != list(b.columns):
        return f"columns differ: {sorted(set(a.columns) ^ set(b.columns))}"
    if len(a) != len(b):
        return f"{len(a)} rows vs {len(b)} rows"
    for col in a.columns:
        x, y = a[col].to_numpy(), b[col].to_numpy()
        if x.dtype.kind == "f" and y.dtype.kind == "f" and x.dtype == y.dtype:
            same = x.view(f"u{x.dtype.itemsize}") == y.view(f"u{y.dtype.itemsize}")
        else:
            same = np.array([bool(u == v) or (u is v) or (_missing(u) and _missing(v))
                             for u, v in zip(x, y, strict=True)], dtype=bool)
        if not same.all():
            i = int(np.flatnonzero(~same)[0])
            where = ", ".join(f"{k}={a.at[i, k]}" for k in KEYS if k in a.columns)
            return f"column {col} differs at row {i} ({where}): {x[i]!r} vs {y[i]!r}"
    return None


def compare(left: Path, right: Path, names: tuple[str, str] = ("left", "right")) -> tuple[bool, list[str]]:
    """Compare the train and eval rows of two runs; (equal, lines to print)."""
    lines, equal = [], True
    for table in ("train", "eval"):
        a, b = load_rows(left, table), load_rows(right, table)
        if a.empty and b.empty:
            lines.append(f"{table}: no rows in either run")
            continue
        diff = first_difference(a, b)
        if diff is None:
            cells = a["cell_id"].nunique() if "cell_id" in a.columns else 0
            lines.append(f"{table}: {names[1]} == {names[0]} for every row ({len(a)} rows, {cells} cells)")
        else:
            equal = False
            lines.append(f"{table}: {names[1]} != {names[0]}: {diff}")
    return equal, lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("left", type=Path)
    ap.add_argument("right", type=Path)
    ap.add_argument("--names", nargs=2, default=("left", "right"), metavar=("LEFT", "RIGHT"))
    args = ap.parse_args(argv)
    for run in (args.left, args.right):
        if not (run / "cells.parquet").is_file():
            print(f"compare_runs: {run} is not a run folder (no cells.parquet)", file=sys.stderr)
            return 2
    equal, lines = compare(args.left, args.right, tuple(args.names))
    print("\n".join(lines))
    return 0 if equal else 1


if __name__ == "__main__":
    sys.exit(main())
