"""Checksums of a run's stored files, and the checks that find a damaged or misplaced file.

``RUN/checksums.json`` (written by the driver of ``bench run`` and ``bench matrix``,
atomically, *before* each file it records)::

    {"format": "warehouse-marl-bench/checksums", "version": 1, "algorithm": "sha256",
     "files": {"eval/<cell_id>.parquet": ["<sha256>"], "cells.parquet": ["<old>", "<new>"], ...}}

An entry lists the digests the file may have: the one last written and, for a rewrite, the
one before it, so a crash between checksums.json and the file's rename leaves a file the
list accepts. A file whose digest is in no entry's list is *damaged* (bit rot, an outside
edit). Independent of checksums, every eval file, train part and matrix file must read as
Parquet and hold rows of the cell its name says (``cell_id`` column): a copied or renamed
file is *misplaced*. ``bench run --repair`` moves damaged and misplaced files to
``RUN/superseded/repair-<UTC time>/`` (with ``repair.json`` saying why) and recomputes
those cells only; without it ``bench run`` refuses, naming the file (exit 2, nothing
written), and ``bench report`` leaves the file out with a warning.

Stores without checksums (written before integrity checks existed: reproduction/paper,
reproduction/ablation, and runs of an older bench) are checked for readability and
placement only. Checksums are *in force* when checksums.json exists and the manifest's
latest run record says ``"checksums": 1``; an older bench that resumed such a store since
leaves its latest record without the flag, and the checksums (possibly stale) are then not
enforced: the next ``bench run`` keeps the entries its files still match and records every
file it writes from then on (docs/decisions/0158).
"""
from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, ValidationError

from bench.store.checkpoints import load_checkpoint
from envs.errors import BenchError

CHECKSUMS_FILE = "checksums.json"
CHECKSUMS_FORMAT = "warehouse-marl-bench/checksums"
RUN_FLAG = "checksums"  # key of a manifest run record written by an integrity-aware bench
REPAIR_PREFIX = "repair-"
REPAIR_FILE = "repair.json"
_HEX64 = re.compile(r"[0-9a-f]{64}")


class ChecksumsFile(BaseModel):
    """Schema of checksums.json (validated on read)."""

    model_config = ConfigDict(extra="forbid")
    format: Literal["warehouse-marl-bench/checksums"]
    version: Literal[1]
    algorithm: Literal["sha256"]
    files: dict[str, list[str]]


def digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def file_digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def repair_hint(rel: str = "") -> str:
    """The command that repairs the stored file ``rel`` (a path inside the run)."""
    if rel.startswith("matrix/"):
        return ("rerun `bench matrix` (same --run and conditions) with --repair: it moves the file to "
                "superseded/ and evaluates that unit again")
    return ("rerun `bench run` (same grid and --out) with --repair: it moves the file to "
            "superseded/ and recomputes that cell only")


class Checksums:
    """The checksums of one run directory; ``active`` when they are in force (see above)."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self.path = self.root / CHECKSUMS_FILE
        self.files: dict[str, list[str]] = {}
        self.active = False  # verified on read
        self.recording = False  # bench run / matrix of this process records its writes

    @classmethod
    def load(cls, root: Path, manifest: Mapping[str, Any] | None) -> Checksums:
        """Read checksums.json (BenchError naming it when it is not valid JSON of the schema)."""
        out = cls(root)
        if not out.path.is_file():
            return out
        try:
            data = ChecksumsFile.model_validate(json.loads(out.path.read_text(encoding="utf-8")))
        except (OSError, ValueError) as exc:
            reason = _validation_line(exc) if isinstance(exc, ValidationError) else " ".join(str(exc).split())[:200]
            raise BenchError(f"corrupt {str(out.path)!r}: {reason}; {_DELETE_HINT}") from None
        bad = next((k for k, v in data.files.items() if not v or not all(_HEX64.fullmatch(d) for d in v)), None)
        if bad is not None:
            raise BenchError(f"corrupt {str(out.path)!r}: entry {bad!r} is not a list of SHA-256 digests; "
                             f"{_DELETE_HINT}")
        out.files = dict(data.files)
        runs = (manifest or {}).get("runs") or []
        out.active = bool(runs) and isinstance(runs[-1], Mapping) and runs[-1].get(RUN_FLAG) == 1
        return out

    # ------------------------------------------------------------- checking
    def rel(self, path: Path) -> str:
        return Path(path).relative_to(self.root).as_posix()

    def mismatch(self, path: Path) -> str:
        """'' when ``path`` is unrecorded or matches its entry, else why it is damaged."""
        if not self.active:
            return ""
        accepted = self.files.get(self.rel(path))
        if not accepted:
            return ""
        found = file_digest(path)
        if found in accepted:
            return ""
        return (f"its SHA-256 {found[:12]}... is not the {accepted[-1][:12]}... recorded when the bench "
                "wrote it (bit rot or an outside change)")

    # ------------------------------------------------------------- recording
    def start_recording(self) -> None:
        """For a writing command: drop entries of absent files (and, when the checksums
        were not in force, entries the files no longer match), then record from now on."""
        kept = {}
        for rel, accepted in self.files.items():
            p = self.root / rel
            if p.is_file() and (self.active or file_digest(p) in accepted):
                kept[rel] = accepted if self.active else [file_digest(p)]
        self.files, self.active, self.recording = kept, True, True
        self._write()

    def before_write(self, path: Path, data: bytes) -> None:
        """Record ``data``'s digest for ``path`` (keeping the previous one until the rename)."""
        if not self.recording:
            return
        rel, new = self.rel(path), digest(data)
        old = self.files.get(rel, [])[-1:]
        self.files[rel] = [d for d in old if d != new] + [new]
        self._write()

    def forget(self, paths: Iterable[Path]) -> None:
        if not self.recording:
            return
        gone = [self.rel(p) for p in paths if self.rel(p) in self.files]
        for rel in gone:
            del self.files[rel]
        if gone:
            self._write()

    def _write(self) -> None:
        from envs.atomic import atomic_file

        body = {"format": CHECKSUMS_FORMAT, "version": 1, "algorithm": "sha256",
                "files": dict(sorted(self.files.items()))}
        with atomic_file(self.path) as fh:
            fh.write(json.dumps(body, indent=0, sort_keys=True).encode() + b"\n")


_DELETE_HINT = ("the bench wrote it; delete it to stop checksum verification of this run "
                "(the next `bench run` starts recording again)")


def _validation_line(exc: ValidationError) -> str:
    err = exc.errors()[0]
    loc = ".".join(str(p) for p in err["loc"]) or "(top level)"
    return f"{loc}: {err['msg']}"


# ------------------------------------------------------------------ damage
@dataclass(frozen=True)
class Damage:
    """A stored file that cannot be trusted: ``rel`` (path in the run), ``cell_id`` (the
    cell it belongs to, '' for cells.parquet), ``why``."""

    rel: str
    cell_id: str
    why: str

    def line(self) -> str:
        return f"damaged file {self.rel}: {self.why}; {repair_hint(self.rel)}"


def inner_cell_ids(path: Path) -> set[str]:
    """The distinct ``cell_id`` values of a Parquet file of ours; every page is read, so a
    page checksum (files written since page checksums) is verified too."""
    import pyarrow.parquet as pq

    table = pq.ParquetFile(path, page_checksum_verification=True).read(use_threads=False)  # 10x read_table
    col = table.column("cell_id")
    return {str(v) for v in col.unique().to_pylist()}


def placement_problem(path: Path, cell_id: str) -> str:
    """'' when ``path`` reads and holds rows of ``cell_id`` only, else why not."""
    import pyarrow as pa

    try:
        found = inner_cell_ids(path)
    except (OSError, pa.ArrowException, KeyError) as exc:
        return f"corrupt Parquet ({' '.join(str(exc).split())[:160]})"
    if found and found != {cell_id}:
        others = ", ".join(sorted(found - {cell_id})) or "none"
        return f"it holds rows of cell {others}, not of {cell_id} (a copied or renamed file)"
    return ""


def find_damage(store: Any, checksums: Checksums, cell_ids: set[str] | None = None,
                load_checkpoints: bool = False) -> list[Damage]:
    """Every damaged or misplaced file of ``store`` (a ``bench.store.run_store.RunStore``), restricted
    to ``cell_ids`` when given (cells.parquet is always checked). Reads every Parquet file
    (page checksums, ``cell_id`` column) and hashes every recorded file; an unrecorded
    checkpoint is loaded only with ``load_checkpoints`` (a resume, which needs them; the
    report does not read checkpoints)."""
    out = []
    for path in store.bench_files():
        if path.name.startswith(".") or path.name == "manifest.json" or path == checksums.path:
            continue
        rel = checksums.rel(path)
        cid = owner_cell(rel)
        if cell_ids is not None and cid and cid not in cell_ids:
            continue
        why = ""
        if rel.endswith(".parquet"):  # misplaced first: a copy's checksum is wrong too, less telling
            why = placement_problem(path, cid) if cid else _readable(path)
        why = why or checksums.mismatch(path)
        if (not why and load_checkpoints and rel.endswith(".pt")
                and not (checksums.active and rel in checksums.files)):
            why = _loadable(path)  # an unrecorded checkpoint: torch's own CRCs tell
        if why:
            out.append(Damage(rel, cid, why))
    return out


def owner_cell(rel: str) -> str:
    """The cell a stored file belongs to ('' for cells.parquet)."""
    parts = rel.split("/")
    if parts[0] in ("eval", "checkpoints"):
        return parts[-1].rsplit(".", 1)[0]
    if parts[0] in ("train", "matrix") and len(parts) == 3:
        return parts[1]
    return ""


def _readable(path: Path) -> str:
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        pq.ParquetFile(path, page_checksum_verification=True).read(use_threads=False)
    except (OSError, pa.ArrowException) as exc:
        return f"corrupt Parquet ({' '.join(str(exc).split())[:160]})"
    return ""


def _loadable(path: Path) -> str:
    try:
        load_checkpoint(path)
    except BenchError as exc:
        return str(exc).replace(f"{str(path)!r}", "").replace("  ", " ").strip()
    return ""


def move_aside(store: Any, checksums: Checksums, damage: list[Damage], stamp: str) -> Path | None:
    """Move every damaged file to superseded/repair-<stamp>/<its path in the run> with
    repair.json (file, cell, why); their checksum entries are dropped. Nothing is deleted."""
    import os

    if not damage:
        return None
    base: Path = store.root / "superseded" / f"{REPAIR_PREFIX}{stamp}"
    dest, k = base, 1
    while dest.exists():  # a second repair within the same second keeps the first one's files
        k += 1
        dest = base.with_name(f"{base.name}-{k}")
    dest.mkdir(parents=True)
    for d in damage:
        target = dest / d.rel
        target.parent.mkdir(parents=True, exist_ok=True)
        os.replace(store.root / d.rel, target)
    checksums.forget([store.root / d.rel for d in damage])
    (dest / REPAIR_FILE).write_text(json.dumps(
        [{"file": d.rel, "cell_id": d.cell_id, "why": d.why} for d in damage], indent=1) + "\n")
    return dest
