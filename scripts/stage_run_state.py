"""Stage a committed run folder's resumable state in git (long runs continue on
any fresh clone).

    .venv/bin/python scripts/stage_run_state.py reproduction/paper [--dry-run]
    git commit -m "reproduction/paper: state at ..."

Stages what a rerun of ``bench run`` needs to resume and what ``bench report`` reads:
``cells.parquet``, ``manifest.json``, ``checksums.json`` (a clone's ``bench run`` checks the
stored files against it, bench/store/integrity.py), ``train/``, ``eval/``, ``matrix/`` and
``report/`` when present, the rows of ``superseded/`` cells (trained with other parameters; not their
checkpoints), and the checkpoints of the cells that are not done (a resumed cell restarts
from them). Checkpoints of done cells stay out of git (``reproduction/.gitignore``) and are
removed from the index if an earlier commit held them while the cell was running; the files
on disk are never touched. A run that is still going (it holds the run folder's lock) is
refused: its tables change while git reads them (a done cell could be staged without its
evaluation rows; tests/reproduction catches that).
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import pandas as pd

from bench.store.checkpoints import checkpoint_cell
from bench.store.run_store import RunStore
from envs.errors import BenchError

DATA = ("cells.parquet", "manifest.json", "checksums.json", "train", "eval", "matrix", "report")


def _cell(ckpt: Path) -> str:
    """The cell of a checkpoint file: ``<method>-<cell_id>.pt`` or the older ``<cell_id>.pt``."""
    return checkpoint_cell(ckpt.name) or ckpt.stem


def plan(run: Path, tracked: set[str]) -> tuple[list[str], list[str]]:
    """(paths to add, tracked checkpoint paths to drop from the index) for ``run``."""
    cells = pd.read_parquet(run / "cells.parquet", columns=["cell_id", "status"])
    unfinished = set(cells.loc[cells["status"] != "done", "cell_id"])
    add = [str(run / name) for name in DATA if (run / name).exists()]
    ckpts = sorted((run / "checkpoints").glob("*.pt")) if (run / "checkpoints").exists() else []
    add += [str(p) for p in ckpts if _cell(p) in unfinished]
    old = run / "superseded"
    add += [str(p) for p in sorted(old.rglob("*")) if p.is_file() and p.suffix in (".parquet", ".json")] \
        if old.is_dir() else []
    drop = sorted(t for t in tracked
                  if Path(t).parent == run / "checkpoints" and _cell(Path(t)) not in unfinished)
    return add, drop


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path, help="the run folder, e.g. reproduction/paper")
    ap.add_argument("--dry-run", action="store_true", help="print the git commands only")
    args = ap.parse_args()
    run = args.run
    if not (run / "cells.parquet").is_file() or not (run / "manifest.json").is_file():
        print(f"stage_run_state: {run} is not a bench run folder (no cells.parquet/manifest.json)", file=sys.stderr)
        return 2
    try:  # a live run rewrites its tables while git reads them: stage only a stopped run
        fd = RunStore(run).lock()
    except BenchError:
        print(f"stage_run_state: a bench run is still writing {run}; stop it first (Ctrl-C or SIGTERM keeps "
              "its checkpoints), then stage", file=sys.stderr)
        return 2
    if fd is not None:
        os.close(fd)
    tracked = set(subprocess.run(["git", "ls-files", "--", str(run / "checkpoints")], capture_output=True,
                                 text=True, check=True).stdout.split())
    add, drop = plan(run, tracked)
    cmds = (([["git", "rm", "--cached", "--force", "--quiet", "--", *drop]] if drop else [])
            + [["git", "add", "-f", "--", *add]])
    for cmd in cmds:
        print(" ".join(cmd))
        if not args.dry_run:
            subprocess.run(cmd, check=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
