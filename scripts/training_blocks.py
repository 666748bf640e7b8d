"""Training rows of a run in blocks of episodes: per method, the mean over its cells (seeds)
of each block's per-episode success, collision, correction and fallback rates (sampled
execution, as trained), team return and episode length (steps). Used for finding
2026-12-08 (the tuned presets at the paper's budget), e.g.

    .venv/bin/python scripts/training_blocks.py reproduction/tuned-n40 --block 400

Prints a Markdown table; a cell still training contributes the blocks it has reached, and
the ``cells`` column says how many cells each block averages. A folder without cells:
one line on stderr, exit status 2.
"""
from __future__ import annotations

import argparse
import sys

import pandas as pd

from bench.store.run_store import RunStore

RATES = ("success_rate", "collision_rate", "correction_rate", "fallback_rate")
MEANS = ("team_return", "steps")
COLUMNS = (*RATES, *MEANS)


def blocks(run: str, block: int) -> pd.DataFrame:
    """One row per (method, block): the mean over cells of each cell's block mean."""
    store = RunStore(run)
    cells = store.read_cells()
    if cells is None:
        print(f"training_blocks: {run!r} is no bench run folder (no cells.parquet)", file=sys.stderr)
        raise SystemExit(2)
    rows = store.read_train().merge(cells[["cell_id", "method"]], on="cell_id")
    rows["block"] = rows["episode"] // block * block
    per_cell = rows.groupby(["method", "block", "cell_id"])[list(COLUMNS)].mean()
    out = per_cell.groupby(["method", "block"]).mean()
    out["cells"] = per_cell.groupby(["method", "block"]).size()
    return out.reset_index()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", help="a bench run directory")
    ap.add_argument("--block", type=int, default=400, help="episodes per block (>= 1)")
    args = ap.parse_args()
    if args.block < 1:
        ap.error(f"--block must be at least 1, got {args.block}")
    table = blocks(args.run, args.block)
    table["episodes"] = [f"{b}-{b + args.block - 1}" for b in table.pop("block")]
    for col in RATES:
        table[col] = (100 * table[col]).map(lambda v: "" if pd.isna(v) else f"{v:.2f}%")
    for col in MEANS:
        table[col] = table[col].map(lambda v: f"{v:.1f}")
    cols = ["method", "episodes", "cells", *COLUMNS]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for _, r in table[cols].iterrows():
        print("| " + " | ".join(str(r[c]) for c in cols) + " |")


if __name__ == "__main__":
    main()
