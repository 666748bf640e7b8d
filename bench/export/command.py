"""``bench export``: read a run's store, build the chosen export, write it atomically.

Nothing in the run folder changes except ``RUN/export/`` (the default target). A file the
export would write that already exists, at the default target or at ``--out``, is refused
unless ``--yes`` (the same rule on every path: an export is never replaced silently).
"""
from __future__ import annotations

import json
from pathlib import Path

from bench.store.run_store import RunStore
from envs.atomic import atomic_file
from envs.errors import BenchError

CSV_TABLES = ("cells", "train", "eval")


def export_run(run: Path, fmt: str, out: Path | None = None, *, execution: str = "argmax",
               balanced: bool = False, overwrite: bool = False) -> list[Path]:
    """Write the export of ``run`` in format ``fmt`` (``marl-eval`` or ``csv``); the paths written."""
    store = RunStore(run)
    cells = store.read_cells()
    if cells is None:
        raise BenchError(f"bench export: {str(run)!r} has no cells.parquet")
    if fmt == "marl-eval":
        from bench.export.to_marl_eval import marl_eval_data

        target = run / "export" / "marl-eval.json" if out is None else out
        if target.is_dir():
            raise BenchError(f"--out {str(target)!r} is a folder; marl-eval's export is one JSON file")
        _refuse_existing([target], overwrite)
        data = marl_eval_data(cells, store.read_train(), store.read_eval(), execution, balanced)
        _write(target, json.dumps(data, indent=1).encode())
        return [target]
    if fmt == "csv":
        from bench.export.to_csv import tidy_tables, to_csv_bytes

        folder = run / "export" / "csv" if out is None else out
        if folder.exists() and not folder.is_dir():
            raise BenchError(f"--out {str(folder)!r} is a file; the csv export writes a folder")
        targets = [folder / f"{name}.csv" for name in CSV_TABLES]
        _refuse_existing(targets, overwrite)
        tables = tidy_tables(cells, store.read_train(), store.read_eval())
        for name, target in zip(CSV_TABLES, targets, strict=True):
            _write(target, to_csv_bytes(tables[name]))
        return targets
    raise BenchError(f"--format {fmt!r}: choose marl-eval or csv")


def _refuse_existing(targets: list[Path], allowed: bool) -> None:
    existing = [t for t in targets if t.exists()]
    if existing and not allowed:
        raise BenchError(f"bench export: {str(existing[0])!r} exists; pass --yes to replace it")


def _write(target: Path, data: bytes) -> None:
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with atomic_file(target) as fh:
            fh.write(data)
    except BenchError:
        raise  # a full disk: DiskFull names the file already
    except OSError as exc:  # read-only file system, permissions (D21: every format says one line)
        raise BenchError(f"cannot write {str(target)!r}: {exc.strerror or exc}") from None
