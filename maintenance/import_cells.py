"""Copy the done cells of one run folder that belong to a grid into another run folder, so
that a bigger grid reuses what a smaller one already trained (the full grid reuses the 84
cells of the committed paper reproduction: same cell ids, same code).

    .venv/bin/python maintenance/import_cells.py --from reproduction/paper --to reproduction/full --grid full
    .venv/bin/bench run --grid full --out reproduction/full      # trains only the rest

Copies, never links: the two folders are published and rebuilt independently, and a link
would tie one report to the other's files. For every imported cell: its train parts, its
eval file and its ``cells.parquet`` row (status done, wall time, attempts, versions as
stored). The target manifest gets one record per source run (commit, machine, workers and
wall time of the parts that trained the imported cells, marked ``imported_from``) and one
record of the import itself. Cells already in the target are left alone; a target cell
with other files is refused. Nothing in the source is touched.
"""
from __future__ import annotations

import argparse
import shutil
import sys
from datetime import datetime, timezone
from pathlib import Path

import pandas as pd

from bench.design.grids import get_grid
from bench.store.run_store import RunStore
from bench.store.schema import SCHEMA_VERSION
from envs.errors import BenchError


def import_cells(src: Path, dst: Path, grid_name: str) -> list[str]:
    """Copy ``src``'s done cells of grid ``grid_name`` into ``dst``; returns their ids."""
    source, target = RunStore(src), RunStore(dst)
    manifest = source.require_run()
    cells = source.read_cells()
    if cells is None:
        raise BenchError(f"{str(src)!r} has no cells.parquet")
    wanted = {c.cell_id for c in get_grid(grid_name).cells}
    have = target.read_cells()
    present = set(have.cell_id) if have is not None else set()
    rows = cells[(cells.status == "done") & cells.cell_id.isin(wanted) & ~cells.cell_id.isin(present)]
    for cid in rows.cell_id:
        if target.has_results(cid):
            raise BenchError(f"{str(dst)!r} already holds files of cell {cid}; not overwritten")
    checks = target.integrity()  # a target whose checksums are in force keeps them (bench/store/integrity.py)
    if checks.active:
        checks.start_recording()
    for cid in rows.cell_id:
        if (source.train_dir / cid).is_dir():  # a planner cell has no training rows
            for _, part in source.train_parts(cid):
                checks.before_write(target.train_dir / cid / part.name, part.read_bytes())
            shutil.copytree(source.train_dir / cid, target.train_dir / cid)
        target.eval_dir.mkdir(parents=True, exist_ok=True)
        checks.before_write(target.eval_path(cid), source.eval_path(cid).read_bytes())
        shutil.copy2(source.eval_path(cid), target.eval_path(cid))
    out_rows = pd.concat([have, rows], ignore_index=True) if have is not None else rows
    target.write_cells(out_rows.to_dict("records"))
    now = datetime.now(timezone.utc).isoformat(timespec="seconds")
    old = target.read_manifest() or {"created": now, "runs": [], "schema_version": SCHEMA_VERSION}
    imported = [{**r, "imported_from": str(src)} for r in manifest.get("runs", [])]
    old["runs"] = list(old.get("runs", [])) + imported + [{
        "imported_from": str(src), "started": now, "ended": now, "grid": grid_name,
        "cells_imported": len(rows), "note": "cells copied from a finished run of the same code "
        "(same cell ids); the records above with imported_from are the runs that trained them",
        **({"checksums": 1} if checks.recording else {}),
    }]
    old.update({"updated": now, "grid": grid_name, "schema_version": SCHEMA_VERSION})
    target.write_manifest(old)
    return list(rows.cell_id)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--from", dest="src", type=Path, required=True)
    ap.add_argument("--to", dest="dst", type=Path, required=True)
    ap.add_argument("--grid", required=True)
    args = ap.parse_args(argv)
    try:
        ids = import_cells(args.src, args.dst, args.grid)
    except BenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"imported {len(ids)} done cells from {args.src} into {args.dst}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
