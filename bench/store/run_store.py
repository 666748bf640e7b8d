"""The crash-safe Parquet store of one run directory (layout: docs/results-schema.md).

    <run>/manifest.json            versions, grid, command line, times
    <run>/cells.parquet            one row per cell (written only by the driver)
    <run>/train/<cell_id>/part-<first_episode>.parquet
    <run>/eval/<cell_id>.parquet   written once, after every evaluation chunk
    <run>/checkpoints/<method>-<cell_id>.pt   (<cell_id>.pt in runs written before)

Every write is atomic (envs/atomic.py: temp file, fsync, rename; permissions from the
umask; a full disk is one ``DiskFull`` line naming the file, the old file kept). Tables
and checkpoints are serialized in memory first, so the only disk write is one ``write``
of the temp file. Crash consistency of training rows: a part covering episodes [a, b) is written
*before* the checkpoint at episode b; on resume, parts starting at or beyond the
checkpoint's episode counter are deleted, so rows are never duplicated or lost.
"""
from __future__ import annotations

import io
import json
import os
import re
from collections.abc import Mapping, Sequence
from contextlib import suppress
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from bench.store.checkpoints import CHECKPOINT_FORMAT, checkpoint_cell, checkpoint_name, load_checkpoint, short_error
from bench.store.integrity import CHECKSUMS_FILE, Checksums, Damage, not_plain, owner_cell
from bench.store.meta_schema import EvalMeta, Manifest, validated
from bench.store.schema import (
    ADDED_CELL_COLUMNS,
    CELLS_SCHEMA,
    EVAL_SCHEMA,
    SCHEMA_VERSION,
    TRAIN_SCHEMA,
    added_columns,
    file_version,
    rows_to_table,
)
from envs.atomic import atomic_file, temp_target
from envs.errors import BenchError

__all__ = ["RunStore", "read_meta", "read_table", "write_table"]

PART_PREFIX, PART_SUFFIX = "part-", ".parquet"
CELL_ID_RE = re.compile(r"[0-9a-f]{12}")  # bench/design/cells.py: 12 hex digits of SHA-256


def table_bytes(table: pa.Table) -> bytes:
    """A Parquet file of ``table`` in memory, with CRC-32 page checksums (verified by
    ``read_table``; the rows are the same as without them)."""
    sink = pa.BufferOutputStream()  # serialize first: the only disk write is fh.write
    pq.write_table(table, sink, write_page_checksum=True)
    data: bytes = sink.getvalue().to_pybytes()  # pyarrow has no type stubs
    return data


def write_table(path: Path, table: pa.Table, checksums: Checksums | None = None) -> None:
    """Write ``table`` to ``path`` atomically; its digest goes to ``checksums`` first."""
    data = table_bytes(table)
    if checksums is not None:
        checksums.before_write(path, data)
    with atomic_file(path) as fh:
        fh.write(data)


def read_table(path: Path, expected: pa.Schema, added: Mapping[str, Any] | None = None) -> pa.Table:
    """Read one Parquet file of ours; corrupt, foreign or other-version files -> BenchError.
    A column of ``added`` (name -> value; default: the schema's ``added_columns``) that the
    file lacks is filled with its value, of the column's type in ``expected``."""
    try:
        table = pq.read_table(path, page_checksum_verification=True)
    except (OSError, pa.ArrowException) as exc:
        raise BenchError(f"corrupt Parquet file {str(path)!r}: {short_error(exc)}") from None
    _check_version(path, table.schema.metadata)
    for name, value in (added_columns(expected) if added is None else added).items():
        if name not in table.schema.names:
            field = expected.field(name)
            table = table.append_column(field, pa.array([value] * table.num_rows, field.type))
    missing = [n for n in expected.names if n not in table.schema.names]
    if missing:
        raise BenchError(f"Parquet file {str(path)!r} lacks column {missing[0]!r}")
    return table


def read_meta(path: Path) -> dict[str, str]:
    """Key-value metadata of a Parquet file (footer only); BenchError when corrupt."""
    try:
        meta = pq.read_schema(path).metadata or {}
    except (OSError, pa.ArrowException) as exc:
        raise BenchError(f"corrupt Parquet file {str(path)!r}: {short_error(exc)}") from None
    _check_version(path, meta)
    return {k.decode(): v.decode() for k, v in meta.items() if k != b"ARROW:schema"}


def _check_version(path: Path, meta: Mapping[bytes, bytes] | None) -> None:
    version = file_version(meta)
    if version != SCHEMA_VERSION:
        raise BenchError(
            f"{str(path)!r} was written with results schema version {version}, this bench "
            f"reads version {SCHEMA_VERSION}; use another --out or --fresh"
        )


class RunStore:
    """Reads and writes one run directory; see the module docstring for the layout."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        self.manifest_path = self.root / "manifest.json"
        self.cells_path = self.root / "cells.parquet"
        self.train_dir = self.root / "train"
        self.eval_dir = self.root / "eval"
        self.ckpt_dir = self.root / "checkpoints"
        self.checksums: Checksums | None = None  # set by integrity(); records writes once started

    def integrity(self) -> Checksums:
        """The run's checksums (bench/store/integrity.py), read once (BenchError when corrupt)."""
        if self.checksums is None:
            self.checksums = Checksums.load(self.root, self.read_manifest())
        return self.checksums

    # ----------------------------------------------------------- validation
    def check_writable(self, repair: bool = False) -> None:
        """BenchError unless ``root`` is (or can become) a writable directory. Writes nothing.
        With ``repair``, a file where a folder of the run belongs is left to ``--repair``."""
        p = self.root
        while not p.exists():
            if p.parent == p:
                break
            p = p.parent
        if not p.is_dir():
            raise BenchError(f"--out {str(self.root)!r}: {str(p)!r} exists and is not a directory")
        if not os.access(p, os.W_OK | os.X_OK):
            raise BenchError(f"--out {str(self.root)!r}: directory {str(p)!r} is not writable")
        if self.root.exists() and not repair:
            for sub in (self.train_dir, self.eval_dir, self.ckpt_dir):
                if sub.exists() and not sub.is_dir():
                    raise BenchError(f"--out {str(self.root)!r}: {str(sub)!r} is not a directory; rerun with "
                                     "--repair to move it to superseded/ and recompute what belongs there")

    def lock(self) -> int | None:
        """Exclusive lock on the run directory (flock on the directory itself: no file is
        created); None if the directory does not exist yet. BenchError if another run holds it.
        Release with ``os.close(fd)``."""
        if not self.root.is_dir():
            return None
        try:
            import fcntl
        except ImportError:  # pragma: no cover - not POSIX
            return None
        fd = os.open(self.root, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise BenchError(f"another bench run is using {str(self.root)!r}; wait for it or use another "
                             "--out") from None
        return fd

    def exists(self) -> bool:
        return self.manifest_path.exists() or self.cells_path.exists()

    def read_manifest(self) -> dict[str, Any] | None:
        if not self.manifest_path.exists():
            return None
        try:
            data = json.loads(self.manifest_path.read_text())
        except (OSError, ValueError) as exc:
            raise BenchError(f"corrupt manifest {str(self.manifest_path)!r}: {short_error(exc)}") from None
        if not isinstance(data, dict) or data.get("schema_version") != SCHEMA_VERSION:
            found = data.get("schema_version") if isinstance(data, dict) else None
            raise BenchError(
                f"{str(self.root)!r} was written with results schema version {found}, this bench "
                f"reads version {SCHEMA_VERSION}; use another --out or --fresh"
            )
        return validated(Manifest, data, self.manifest_path)

    def require_run(self) -> dict[str, Any]:
        """The manifest of an existing run directory (for report/replay), else BenchError."""
        manifest = self.read_manifest()
        if manifest is None:
            raise BenchError(f"{str(self.root)!r} is not a bench run directory (no manifest.json)")
        return manifest

    # ----------------------------------------------------------------- cells
    def read_cells(self) -> pd.DataFrame | None:
        if not self.cells_path.exists():
            return None
        df = read_table(self.cells_path, CELLS_SCHEMA, ADDED_CELL_COLUMNS).to_pandas()
        return df.fillna(ADDED_CELL_COLUMNS)  # a row written without an added column: its value

    def write_cells(self, rows: Sequence[Mapping[str, Any]]) -> None:
        write_table(self.cells_path, rows_to_table(rows, CELLS_SCHEMA), self.checksums)

    def write_manifest(self, data: Mapping[str, Any]) -> None:
        with atomic_file(self.manifest_path) as fh:
            fh.write(json.dumps(dict(data), indent=2, sort_keys=True).encode() + b"\n")

    # ------------------------------------------------------------ train rows
    def _part_path(self, cell_id: str, first_episode: int) -> Path:
        return self.train_dir / cell_id / f"{PART_PREFIX}{first_episode:09d}{PART_SUFFIX}"

    def train_parts(self, cell_id: str) -> list[tuple[int, Path]]:
        """(first_episode, path) of a cell's committed train parts, sorted."""
        d = self.train_dir / cell_id
        if not d.is_dir():
            return []
        out = []
        for p in d.iterdir():
            if p.name.startswith(PART_PREFIX) and p.name.endswith(PART_SUFFIX):
                try:
                    out.append((int(p.name[len(PART_PREFIX):-len(PART_SUFFIX)]), p))
                except ValueError:
                    continue
        return sorted(out)

    def write_train_part(self, cell_id: str, first_episode: int, rows: Sequence[Mapping[str, Any]]) -> None:
        rows = [{**r, "cell_id": cell_id} for r in rows]
        write_table(self._part_path(cell_id, first_episode), rows_to_table(rows, TRAIN_SCHEMA), self.checksums)

    def discard_parts_from(self, cell_id: str, episode: int) -> int:
        """Delete parts starting at or after ``episode`` (not covered by the checkpoint)."""
        gone = [path for first, path in self.train_parts(cell_id) if first >= episode]
        for path in gone:
            path.unlink()
        if self.checksums is not None:
            self.checksums.forget(gone)
        return len(gone)

    def read_train(self) -> pd.DataFrame:
        return self.read_rows(self.train_dir, TRAIN_SCHEMA).to_pandas()

    # ------------------------------------------------------------- eval rows
    def eval_path(self, cell_id: str) -> Path:
        return self.eval_dir / f"{cell_id}.parquet"

    def write_eval(self, cell_id: str, rows: Sequence[Mapping[str, Any]], meta: Mapping[str, Any]) -> None:
        rows = [{**r, "cell_id": cell_id} for r in rows]
        extra = {k: json.dumps(v) for k, v in meta.items()}
        write_table(self.eval_path(cell_id), rows_to_table(rows, EVAL_SCHEMA, extra), self.checksums)

    def eval_meta(self, cell_id: str) -> dict[str, Any] | None:
        """Metadata (wall_s, peak_mem_mb, attempts) of a finished cell's eval file, or None."""
        path = self.eval_path(cell_id)
        if not path.exists():
            return None
        out = {}
        for k, v in read_meta(path).items():
            if k == "schema_version":
                continue
            try:
                out[k] = json.loads(v)
            except ValueError:
                out[k] = v
        return validated(EvalMeta, out, f"{path} (key-value metadata)")

    def read_eval(self) -> pd.DataFrame:
        return self.read_rows(self.eval_dir, EVAL_SCHEMA).to_pandas()

    def read_rows(self, root: Path, schema: pa.Schema, problems: list[str] | None = None,
                  checksums: Checksums | None = None, damaged: set[str] | None = None,
                  added: Mapping[str, Any] | None = None) -> pa.Table:
        """Every Parquet file of ours under ``root`` (``train/``, ``eval/`` or ``matrix/``) as one
        table of ``schema``: the one reader of a run's row datasets (the report's too). A file that is unreadable,
        damaged (its digest differs from ``checksums``), a link or inside one (never followed),
        or that holds rows of another cell than its name says is a ``BenchError`` naming it;
        with ``problems``, it is listed there instead (and its cell added to ``damaged``) and
        skipped, so one bad file neither hides the rest of the run nor puts wrong numbers in a
        report (bench/store/integrity.py). Files whose name starts with '.' are temporary.
        ``added``: columns a file may lack and their values (``read_table``)."""
        files = sorted(p for p in root.rglob("*.parquet") if not p.name.startswith(".")) if root.is_dir() else []
        if not files and problems is not None:
            problems.append(f"{root.name}/ holds no Parquet file")
        tables = []
        links = not_plain(root.parent) if files else []
        for path in files:
            rel = path.relative_to(root.parent).as_posix()
            why = next((w for r, _, w in links if rel == r or rel.startswith(r + "/")), "")
            why = why or (checksums.mismatch(path) if checksums is not None else "")
            table = None
            if not why:
                try:
                    table = read_table(path, schema, added).select(schema.names).cast(schema)
                except BenchError as exc:
                    if problems is None:
                        raise
                    why = f"unreadable ({exc})"
            if table is not None:
                cid = owner_cell(rel)
                found = {str(v) for v in table.column("cell_id").unique().to_pylist()}
                if cid and found and found != {cid}:
                    others = ", ".join(sorted(found - {cid}))
                    why = f"it holds rows of cell {others}, not of {cid} (a copied or renamed file)"
            if why:
                line = Damage(rel, owner_cell(rel), why).line()
                if problems is None:
                    raise BenchError(f"{str(self.root)!r}: {line}")
                problems.append(f"skipped {rel}: {line}")
                if damaged is not None:
                    damaged.add(owner_cell(rel))
                continue
            tables.append(table)
        return pa.concat_tables(tables) if tables else schema.empty_table()

    # ----------------------------------------------------------- checkpoints
    def ckpt_path(self, cell_id: str, method: str | None = None) -> Path:
        """The cell's checkpoint file: the stored one, whichever its name
        (``checkpoints/<method>-<cell_id>.pt``, or ``<cell_id>.pt`` as written before names
        carried the method); where none is stored, the name a new one of ``method`` gets."""
        new = self.ckpt_dir / checkpoint_name(cell_id, method)
        old = self.ckpt_dir / checkpoint_name(cell_id)
        if new.exists() or old.exists():
            return new if new.exists() else old
        if method is None and self.ckpt_dir.is_dir():  # the method unknown here: look for its name
            found = [p for p in self.ckpt_dir.glob(f"*-{cell_id}.pt") if checkpoint_cell(p.name) == cell_id]
            if found:
                return min(found)
        return new

    def write_checkpoint(self, cell_id: str, payload: Mapping[str, Any]) -> None:
        """Atomically save ``payload`` (tensors and plain data) to the cell's checkpoint,
        ``checkpoints/<method>-<cell_id>.pt`` (``payload["method"]``); a cell whose checkpoint
        already has the older name ``<cell_id>.pt`` keeps it."""
        import torch

        path = self.ckpt_path(cell_id, payload.get("method"))
        buf = io.BytesIO()  # serialize first: a full disk fails in fh.write, not in torch's zip writer
        torch.save({"format": CHECKPOINT_FORMAT, "schema_version": SCHEMA_VERSION, **payload}, buf)
        if self.checksums is not None:
            self.checksums.before_write(path, buf.getvalue())
        with atomic_file(path) as fh:
            fh.write(buf.getbuffer())

    def read_checkpoint(self, cell_id: str, method: str | None = None) -> dict[str, Any] | None:
        path = self.ckpt_path(cell_id, method)
        return load_checkpoint(path) if path.exists() else None

    # ----------------------------------------------------------- superseded
    def has_results(self, cell_id: str) -> bool:
        """Whether the cell has stored train parts, an eval file, a checkpoint or matrix rows."""
        return bool(self.train_parts(cell_id) or self.eval_path(cell_id).exists()
                    or self.ckpt_path(cell_id).exists() or (self.root / "matrix" / cell_id).is_dir())

    def supersede(self, cell_id: str, row: Mapping[str, Any], stamp: str) -> Path:
        """Move every stored file of a cell (train parts, eval file, checkpoint, matrix rows)
        to superseded/<cell_id>-<stamp>/ with its former cells.parquet row (cells_row.json);
        nothing is deleted, and readers of the run (report, matrix) no longer see them."""
        dest = self.root / "superseded" / f"{cell_id}-{stamp}"
        dest.mkdir(parents=True, exist_ok=False)
        moves = [(p, dest / "train" / p.name) for _, p in self.train_parts(cell_id)]
        moves += [(self.eval_path(cell_id), dest / "eval.parquet"), (self.ckpt_path(cell_id), dest / "checkpoint.pt")]
        matrix = self.root / "matrix" / cell_id
        if matrix.is_dir():
            moves += [(p, dest / "matrix" / p.name) for p in sorted(matrix.iterdir()) if p.is_file()]
        for src, dst in moves:
            if src.exists():
                dst.parent.mkdir(parents=True, exist_ok=True)
                os.replace(src, dst)
        if self.checksums is not None:
            self.checksums.forget(src for src, _ in moves)
        for d in (self.train_dir / cell_id, matrix):
            _rmdir_if_empty(d)
        (dest / "cells_row.json").write_text(json.dumps(dict(row), sort_keys=True, default=str, indent=1) + "\n")
        return dest

    # ------------------------------------------------------------- cleanup
    def remove_temp_files(self) -> int:
        """Delete leftovers of interrupted atomic writes of bench files ('.<name>.*.tmp')."""
        n = 0
        for p in self.bench_files():
            if temp_target(p.name):
                with suppress(OSError):
                    p.unlink()
                    n += 1
        return n

    def bench_files(self) -> list[Path]:
        """Files of this run directory that the bench itself writes (and only those).

        manifest.json, cells.parquet, checksums.json, train/<cell_id>/part-<k>.parquet,
        eval/<cell_id>.parquet, checkpoints/<method>-<cell_id>.pt (or <cell_id>.pt), matrix/<cell_id>/*.parquet
        (``bench matrix``; cell_id: 12 hex digits) and the
        temp files ('.<name>.<random>.tmp') of interrupted writes of these. Anything else,
        and anything behind a symlink, is the user's.
        """
        def plain(d: Path) -> list[tuple[Path, str]]:
            """(file, the name it stands for: its own, or a temp file's target) in ``d``."""
            if not d.is_dir() or d.is_symlink():
                return []
            return [(p, temp_target(p.name) or p.name) for p in d.iterdir() if p.is_file() and not p.is_symlink()]

        out = [p for p, name in plain(self.root) if name in ("manifest.json", "cells.parquet", CHECKSUMS_FILE)]
        if self.train_dir.is_dir() and not self.train_dir.is_symlink():
            for d in self.train_dir.iterdir():
                if CELL_ID_RE.fullmatch(d.name):
                    out += [p for p, name in plain(d) if _is_part(name)]
        out += [p for p, name in plain(self.eval_dir)
                if name.endswith(".parquet") and CELL_ID_RE.fullmatch(name.removesuffix(".parquet"))]
        out += [p for p, name in plain(self.ckpt_dir) if checkpoint_cell(name)]
        matrix = self.root / "matrix"  # bench matrix: matrix/<cell_id>/<condition>.parquet
        if matrix.is_dir() and not matrix.is_symlink():
            for d in matrix.iterdir():
                if CELL_ID_RE.fullmatch(d.name):
                    out += [p for p, name in plain(d) if name.endswith(".parquet")]
        return sorted(out)

    def check_fresh(self) -> None:
        """BenchError unless --fresh may run here: the directory does not exist, is empty,
        or is a bench run directory (has manifest.json). Nothing else is ever wiped."""
        if not self.root.is_dir() or self.manifest_path.is_file():
            return
        if any(self.root.iterdir()):
            raise BenchError(
                f"--fresh: {str(self.root)!r} has files but no manifest.json, so it is not a bench "
                "run directory; refusing to delete anything in it (choose another --out)"
            )

    def wipe(self) -> list[Path]:
        """Delete the files the bench wrote here (``bench_files``) for --fresh; other files and
        the folders holding them stay. Returns the deleted files."""
        files = self.bench_files()
        for p in files:
            p.unlink()
        for p in files:  # train/<cell_id>/ first, then train/, eval/, checkpoints/ (never the root)
            if p.parent != self.root:
                _rmdir_if_empty(p.parent)
        for d in (self.train_dir, self.eval_dir, self.ckpt_dir):
            _rmdir_if_empty(d)
        return files


def _is_part(name: str) -> bool:
    mid = name[len(PART_PREFIX):-len(PART_SUFFIX)]
    return name.startswith(PART_PREFIX) and name.endswith(PART_SUFFIX) and mid.isdigit()


def _rmdir_if_empty(d: Path) -> None:
    if d.is_dir() and not d.is_symlink() and not any(d.iterdir()):
        d.rmdir()
