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

A run whose manifest says it was written with checksums but whose checksums.json is gone
is not trusted silently: every stored file then reads as damaged ("cannot be verified"), so
``bench run`` and ``bench report`` refuse, naming the file, until checksums.json is restored
or ``bench run --repair`` moves the unverifiable files aside and recomputes them
(docs/decisions/0195). A stored file must be a plain file: a symbolic link where the bench
keeps a file or a folder (a link to an edited copy would bypass the check) is damaged too,
said with where it points and whether that is outside the run (docs/decisions/0196), and so
is a plain file where the bench keeps a folder (``eval``, ``train``, ``checkpoints``,
``matrix``).

Stores without checksums (written before integrity checks existed, and runs of an older
bench) are checked for readability and placement only; the committed ones of
reproduction/ have theirs recorded since, marked ``added_later`` (docs/decisions/0197),
which puts them in force as well. Checksums are *in force* when checksums.json exists and the manifest's
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

from bench.store.checkpoints import checkpoint_cell, load_checkpoint
from envs.errors import BenchError

CHECKSUMS_FILE = "checksums.json"
CHECKSUMS_FORMAT = "warehouse-marl-bench/checksums"
RUN_FLAG = "checksums"  # key of a manifest run record written by an integrity-aware bench
REPAIR_PREFIX = "repair-"
REPAIR_FILE = "repair.json"
_HEX64 = re.compile(r"[0-9a-f]{64}")
_CELL_ID = re.compile(r"[0-9a-f]{12}")  # bench/store/run_store.py CELL_ID_RE (not imported: it imports this)


class AddedLater(BaseModel):
    """Digests recorded after the files were written (the committed stores that predate
    checksums, docs/decisions/0197): when, what vouches for the bytes, which files."""

    model_config = ConfigDict(extra="forbid")
    date: str
    note: str
    files: list[str]


class ChecksumsFile(BaseModel):
    """Schema of checksums.json (validated on read)."""

    model_config = ConfigDict(extra="forbid")
    format: Literal["warehouse-marl-bench/checksums"]
    version: Literal[1]
    algorithm: Literal["sha256"]
    files: dict[str, list[str]]
    added_later: AddedLater | None = None


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
    if rel in FOLDERS or (rel.split("/")[0] in FOLDERS and not owner_cell(rel)):  # a folder replaced
        return ("rerun `bench run` (same grid and --out) with --repair: it moves it to superseded/ and "
                "recomputes the cells whose files it held")
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
        self.missing = False  # the manifest says the run was written with checksums, the file is gone
        self.added_later: dict[str, Any] | None = None  # ChecksumsFile.added_later, kept on rewrite

    @classmethod
    def load(cls, root: Path, manifest: Mapping[str, Any] | None) -> Checksums:
        """Read checksums.json (BenchError naming it when it is not valid JSON of the schema)."""
        out = cls(root)
        runs = (manifest or {}).get("runs") or []
        flagged = bool(runs) and isinstance(runs[-1], Mapping) and runs[-1].get(RUN_FLAG) == 1
        if not out.path.is_file():
            out.missing = flagged  # D22: never start afresh over files that cannot be verified
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
        out.added_later = data.added_later.model_dump() if data.added_later is not None else None
        out.active = flagged or data.added_later is not None
        return out

    # ------------------------------------------------------------- checking
    def rel(self, path: Path) -> str:
        return Path(path).relative_to(self.root).as_posix()

    def mismatch(self, path: Path) -> str:
        """'' when ``path`` is unrecorded or matches its entry, else why it is damaged."""
        if self.missing:
            return (f"it cannot be verified: {CHECKSUMS_FILE} is missing although the manifest records that "
                    f"this run was written with checksums (restore {CHECKSUMS_FILE} if you have a copy)")
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
        self.files, self.active, self.recording, self.missing = kept, True, True, False
        self._write()

    def before_write(self, path: Path, data: bytes) -> None:
        """Record ``data``'s digest for ``path`` (keeping the previous one until the rename)."""
        if not self.recording:
            return
        rel, new = self.rel(path), digest(data)
        old = self.files.get(rel, [])[-1:]
        self.files[rel] = [d for d in old if d != new] + [new]
        self._write()

    def add_later(self, paths: Iterable[Path], date: str, note: str) -> list[str]:
        """Record the digests of those ``paths`` that have no entry yet, marked in
        ``added_later`` as recorded after they were written (``note``: what vouches for their
        bytes); the paths added. For the committed stores that predate checksums (0197)."""
        new = sorted(rel for rel in (self.rel(p) for p in paths) if rel not in self.files)
        for rel in new:
            self.files[rel] = [file_digest(self.root / rel)]
        before = (self.added_later or {}).get("files", [])
        self.added_later = {"date": date, "note": note, "files": sorted({*before, *new})}
        self.active = True
        self._write()
        return new

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

        body: dict[str, Any] = {"format": CHECKSUMS_FORMAT, "version": 1, "algorithm": "sha256",
                                "files": dict(sorted(self.files.items()))}
        if self.added_later is not None:
            body["added_later"] = self.added_later
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
    out = [Damage(rel, cid, why) for rel, cid, why in not_plain(store.root)
           if cell_ids is None or not cid or cid in cell_ids]
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


FOLDERS = ("train", "eval", "checkpoints", "matrix")  # the folders of a run the bench keeps


def owner_cell(rel: str) -> str:
    """The cell a stored file belongs to ('' for cells.parquet)."""
    parts = rel.split("/")
    if parts[0] == "checkpoints":
        return checkpoint_cell(parts[-1]) or parts[-1].rsplit(".", 1)[0]
    if parts[0] == "eval":
        return parts[-1].rsplit(".", 1)[0]
    if parts[0] in ("train", "matrix") and len(parts) == 3:
        return parts[1]
    return ""


def not_plain(root: Path) -> list[tuple[str, str, str]]:
    """(path in the run, its cell or '', why) of every entry where the bench keeps a plain file
    or folder that is something else: a symbolic link (followed, it would bypass the
    checksums: D18) or a file standing where a folder belongs (D12). Entries of names the
    bench never writes are the user's and left alone. Reads no file."""
    root = Path(root)
    out: list[tuple[str, str, str]] = []

    def check(path: Path, cid: str, folder: bool) -> bool:
        """Record ``path`` when it is not plain; True when it is a plain folder to look into."""
        rel = path.relative_to(root).as_posix()
        if path.is_symlink():
            out.append((rel, cid, _link_why(root, path)))
            return False
        if folder and path.exists() and not path.is_dir():
            out.append((rel, cid, f"a file stands where the bench keeps its folder {rel}/"))
            return False
        return folder and path.is_dir()

    check(root / "cells.parquet", "", False)
    for name in FOLDERS:
        if not check(root / name, "", True):
            continue
        for sub in sorted((root / name).iterdir()):
            cid = (checkpoint_cell(sub.name) or "") if name == "checkpoints" else sub.name.rsplit(".", 1)[0]
            if not _CELL_ID.fullmatch(cid):
                continue
            if name in ("train", "matrix"):
                if check(sub, cid, True):
                    for p in sorted(sub.iterdir()):
                        if p.suffix == ".parquet":
                            check(p, cid, False)
            elif sub.suffix in (".parquet", ".pt"):
                check(sub, cid, False)
    return out


def _link_why(root: Path, path: Path) -> str:
    import os

    target = os.readlink(path)
    resolved = path.resolve()
    outside = not resolved.is_relative_to(root.resolve())
    return (f"a symbolic link to {target}{' (outside the run)' if outside else ''}; the bench stores "
            "plain files only and never follows a link")


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
