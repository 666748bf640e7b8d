"""Atomic file writes of the bench, and the one message for a full disk.

``atomic_file``: a temporary file in the same directory (its name starts with '.', which
pyarrow's dataset reader ignores), flush + fsync, ``os.replace``, fsync of the directory;
the file gets the permissions the umask gives (like ``open``), not mkstemp's 0600. A full
disk (ENOSPC/EDQUOT, also when a writer wraps it) raises ``DiskFull``, a BenchError naming
the file; the temp file is removed and the previous version stays in place.
"""
from __future__ import annotations

import errno
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

from envs.errors import BenchError

NO_SPACE = (errno.ENOSPC, errno.EDQUOT)


class DiskFull(BenchError):
    """The disk (or quota) filled up while the bench wrote ``path``; nothing stored was damaged."""

    def __init__(self, path: str | Path) -> None:
        self.path = str(path)
        super().__init__(f"disk full while writing {self.path}; nothing stored was damaged; "
                         "free space and rerun to resume")


def is_disk_full(exc: BaseException | None) -> bool:
    """ENOSPC/EDQUOT, also when a writer turned it into another error while cleaning up
    (matplotlib's PDF writer raises AttributeError during the failed write's handling)."""
    seen = 0
    while exc is not None and seen < 10:
        if isinstance(exc, OSError) and exc.errno in NO_SPACE:
            return True
        exc, seen = exc.__cause__ or exc.__context__, seen + 1
    return False


def file_mode() -> int:
    """0666 minus the process umask: what ``open(path, "w")`` would create."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


@contextmanager
def atomic_file(path: Path) -> Iterator[IO[bytes]]:
    """Write ``path`` atomically: temp file in the same dir, fsync, os.replace, dir fsync.

    A full disk (ENOSPC/EDQUOT) raises ``DiskFull`` naming ``path``; the old file is kept.
    """
    tmp = ""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        with os.fdopen(fd, "wb") as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, file_mode())
        os.replace(tmp, path)
    except BaseException as exc:
        if tmp:
            with _suppress_oserror():
                os.unlink(tmp)
        if is_disk_full(exc):
            raise DiskFull(path) from None
        raise
    _fsync_dir(path.parent)


@contextmanager
def _suppress_oserror() -> Iterator[None]:
    try:
        yield
    except OSError:
        pass


def _fsync_dir(path: Path) -> None:
    with _suppress_oserror():
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
