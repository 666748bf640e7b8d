"""An Optuna journal file that survives a full disk and an interrupted write (D1).

Optuna's ``JournalFileBackend`` appends one JSON record a line. A write cut short (full
disk, a killed process) leaves a torn last line; Optuna's reader skips a torn *last* line,
but the next append lands right after it, gluing the torn prefix to a whole record, and
from then on every read of the study fails with a JSONDecodeError. Two defences:

* ``SafeJournalFileBackend.append_logs`` (Optuna's own append, under its own lock) truncates
  the file back to its size before the write when the write fails, so a full disk leaves
  whole records only, and names the journal in a ``DiskFull`` error;
* ``repair_journal`` (run when a study is opened, under the same lock) finds a torn record
  -- a last line without its newline, or a line that is a torn prefix glued to a whole
  record (what older versions left) -- keeps every whole record, saves the original bytes
  beside the journal as ``journal.log.torn-<UTC time>`` and returns a line saying what it
  recovered. Any other undecodable line is not a torn write: a BenchError names it.
"""
from __future__ import annotations

import json
import os
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from optuna.storages.journal import JournalFileBackend
from optuna.storages.journal._file import get_lock_file

from envs.atomic import DiskFull, atomic_file, is_disk_full
from envs.errors import BenchError

RECORD_START = b'{"op_code":'  # every record Optuna writes starts so (json.dumps, compact)


class SafeJournalFileBackend(JournalFileBackend):
    """``JournalFileBackend`` whose appends are all-or-nothing and whose torn tail is repaired
    on open (``repaired``: what was recovered, '' when the journal was whole)."""

    def __init__(self, file_path: str) -> None:
        super().__init__(file_path)
        with get_lock_file(self._lock):
            self.repaired = repair_journal(Path(file_path))

    def append_logs(self, logs: list[dict[str, Any]]) -> None:
        with get_lock_file(self._lock):
            data = ("\n".join(json.dumps(log, separators=(",", ":")) for log in logs) + "\n").encode("utf-8")
            with open(self._file_path, "ab") as f:
                size = f.seek(0, os.SEEK_END)
                try:
                    f.write(data)
                    f.flush()
                    os.fsync(f.fileno())
                except BaseException as exc:
                    _truncate(f, size)
                    if is_disk_full(exc):
                        raise DiskFull(self._file_path) from None
                    raise


def _truncate(f: Any, size: int) -> None:
    try:
        f.truncate(size)
        os.fsync(f.fileno())
    except (OSError, ValueError):  # a closed or broken stream: the repair on open handles it
        pass


def _whole(line: bytes) -> bool:
    try:
        return isinstance(json.loads(line), dict)
    except ValueError:
        return False


def repair_journal(path: Path) -> str:
    """Drop torn records from the journal at ``path`` (see the module docstring); '' when it
    was whole, else one line naming what was recovered and where the original is kept."""
    if not path.is_file():
        return ""
    data = path.read_bytes()
    if not data:
        return ""
    lines = data.split(b"\n")
    tail = lines.pop()  # b"" when the file ends with a newline
    kept: list[bytes] = []
    torn: list[str] = []
    for number, line in enumerate(lines, start=1):
        if _whole(line):
            kept.append(line)
            continue
        start = line.rfind(RECORD_START)
        if start > 0 and _whole(line[start:]):  # a torn prefix, then a whole appended record
            kept.append(line[start:])
            torn.append(f"line {number} ({start} bytes)")
            continue
        raise BenchError(f"study journal {str(path)!r}: line {number} is not a JSON record and not a "
                         "torn write the bench can recover; restore the journal from a backup")
    if tail:
        if _whole(tail):  # a whole record that only lacks its newline
            kept.append(tail)
        else:
            torn.append(f"the last line ({len(tail)} bytes)")
    if not torn:
        if tail:  # complete the last record's line, so the next append starts a new one
            _rewrite(path, kept)
        return ""
    stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    backup = path.with_name(f"{path.name}.torn-{stamp}")
    try:
        with atomic_file(backup) as fh:
            fh.write(data)
        _rewrite(path, kept)
    except DiskFull:
        raise DiskFull(path) from None
    return (f"study journal {path}: dropped the torn record(s) of an interrupted write "
            f"({', '.join(torn)}); kept all {len(kept)} whole records; the original is saved as {backup.name}")


def _rewrite(path: Path, kept: list[bytes]) -> None:
    with atomic_file(path) as fh:
        fh.write(b"".join(line + b"\n" for line in kept))
