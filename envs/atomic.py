"""Atomic file writes, the one writer every package uses, and the one message for a full disk.

``atomic_path(path)`` yields a temporary path next to ``path`` (its name ``.<name>.<random>.tmp``
starts with '.', which pyarrow's dataset reader ignores) for any writer that wants a file
name (imageio, ffmpeg, matplotlib, ``shutil.copyfile``); ``atomic_file(path)`` yields a
binary file handle on one. On a clean exit the temporary file is fsynced, given the
permissions the umask gives (like ``open``; mkstemp's 0600 is never left behind), moved
onto ``path`` with ``os.replace`` and the directory is fsynced. On any exit by an exception
(KeyboardInterrupt and SystemExit included) the temporary file is removed and the previous
``path`` stays as it was. A full disk (ENOSPC/EDQUOT, also when a writer wraps it) raises
``DiskFull``, a BenchError naming the file. ``temp_target`` names the file a leftover
temporary (from a SIGKILL or a power loss) stood for, so that cleaners can find them.

The lowest layer that writes files (the distance cache, GIFs) is ``envs``, so the writer
lives here. May import: the standard library and ``envs.errors``.
"""
from __future__ import annotations

import errno
import os
import re
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO

from envs.errors import BenchError

__all__ = ["DiskFull", "atomic_file", "atomic_path", "file_mode", "is_disk_full", "temp_target"]

NO_SPACE = (errno.ENOSPC, errno.EDQUOT)
# '.<target>.<mkstemp's random part>.tmp', optionally followed by the target's own suffix
# (ffmpeg picks its container from the extension: '.clip.mp4.<random>.tmp.mp4').
_TEMP_RE = re.compile(r"\.(?P<target>.+)\.[A-Za-z0-9_]+\.tmp(?P<ext>\.[A-Za-z0-9]+)?")


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


def temp_target(name: str) -> str:
    """The file name a temporary of ``atomic_path`` stands for, else '' (not one of ours)."""
    m = _TEMP_RE.fullmatch(name)
    if m is None or (m["ext"] and not m["target"].endswith(m["ext"])):
        return ""
    return m["target"]


@contextmanager
def atomic_path(path: Path | str, suffix: str = "") -> Iterator[Path]:
    """A temporary path to write ``path``'s new content to; see the module docstring.

    ``suffix`` is appended to the temporary name for writers that choose a format by it
    (``".mp4"``); it must be ``path``'s own suffix.
    """
    path = Path(path)
    tmp = ""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + suffix, dir=path.parent)
        os.close(fd)
        yield Path(tmp)
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.chmod(tmp, file_mode())
        os.replace(tmp, path)
    except BaseException as exc:
        if tmp:
            with suppress(OSError):
                os.unlink(tmp)
        if is_disk_full(exc):
            raise DiskFull(path) from None
        raise
    _fsync_dir(path.parent)


@contextmanager
def atomic_file(path: Path | str) -> Iterator[IO[bytes]]:
    """A binary file handle whose content replaces ``path`` atomically on a clean exit."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        yield fh


def _fsync_dir(path: Path) -> None:
    with suppress(OSError):
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
