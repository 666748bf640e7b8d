"""Split the worker seconds of discarded attempts out of ``wall_s`` in a run written before
``superseded_wall_s`` existed (docs/results-schema.md).

A cell trained again after ``bench run --rerun-changed`` moved its files to
``superseded/<cell_id>-<stamp>/`` used to carry the old attempt's ``wall_s`` into the new one.
For each such cell whose row has no ``superseded_wall_s`` yet, this moves the archived row's
``wall_s`` (the latest archive's: each attempt carried the earlier ones) from ``wall_s`` to
``superseded_wall_s`` in cells.parquet and in the eval file's metadata (which a resume reads
back). A second run changes nothing.

    .venv/bin/python maintenance/split_superseded_wall.py reproduction/paper

Imports: bench.store only.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import pyarrow.parquet as pq

from bench.store.integrity import REPAIR_PREFIX
from bench.store.run_store import RunStore, write_table
from envs.errors import BenchError


def archived_wall(root: Path) -> dict[str, float]:
    """cell_id -> ``wall_s`` of its latest ``superseded/<cell_id>-<stamp>/cells_row.json``."""
    latest: dict[str, tuple[str, float]] = {}
    base = root / "superseded"
    for d in sorted(base.iterdir()) if base.is_dir() else []:
        row_file = d / "cells_row.json"
        if d.name.startswith(REPAIR_PREFIX) or not row_file.is_file():
            continue
        cell_id, _, stamp = d.name.rpartition("-")
        row = json.loads(row_file.read_text())
        if row.get("cell_id", cell_id) != cell_id:
            raise BenchError(f"{row_file}: row of cell {row.get('cell_id')!r} in the folder of {cell_id!r}")
        if cell_id not in latest or stamp > latest[cell_id][0]:
            latest[cell_id] = (stamp, float(row.get("wall_s") or 0.0))
    return {cid: wall for cid, (_, wall) in latest.items()}


def split(root: Path) -> list[str]:
    """Apply the split to the run at ``root``; one line per cell changed."""
    store = RunStore(root)
    cells = store.read_cells()
    if cells is None:
        raise BenchError(f"{root}: no cells.parquet")
    checksums = store.integrity()
    lines = []
    for cid, old in archived_wall(root).items():
        hit = cells.index[cells["cell_id"] == cid]
        if len(hit) != 1 or float(cells.at[hit[0], "superseded_wall_s"]) > 0.0:
            continue  # not in this run, or split already
        i = hit[0]
        total = float(cells.at[i, "wall_s"])
        if not 0.0 <= old <= total:
            raise BenchError(f"{cid}: archived wall_s {old} is not part of its wall_s {total}")
        cells.at[i, "wall_s"], cells.at[i, "superseded_wall_s"] = total - old, old
        path = store.eval_path(cid)
        if path.exists():
            table = pq.read_table(path)
            meta = dict(table.schema.metadata or {})
            meta[b"wall_s"] = json.dumps(total - old).encode()
            write_table(path, table.replace_schema_metadata(meta), checksums)
        lines.append(f"{cid}: wall_s {total:.1f} -> {total - old:.1f}, superseded_wall_s {old:.1f}")
    if lines:
        store.write_cells(cells.to_dict("records"))
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", type=Path, help="run folders (bench run --out)")
    args = ap.parse_args(argv)
    try:
        for root in args.runs:
            lines = split(root)
            print(f"{root}: {len(lines)} cell(s) split")
            for line in lines:
                print(f"  {line}")
    except BenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
