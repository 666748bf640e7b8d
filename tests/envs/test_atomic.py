"""envs/atomic.py: the one atomic writer (mode from the umask, no temp file left on any
exit, the old file intact until the new one is complete)."""
from __future__ import annotations

import errno
import os
from pathlib import Path

import numpy as np
import pytest

import envs.atomic
from envs.atomic import DiskFull, atomic_file, atomic_path, temp_target
from envs.render import write_gif


@pytest.mark.parametrize(("umask", "mode"), [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_atomic__files_get_the_mode_the_umask_gives(tmp_path: Path, umask: int, mode: int) -> None:
    old = os.umask(umask)
    try:
        with atomic_file(tmp_path / "a.bin") as fh:
            fh.write(b"x")
        with atomic_path(tmp_path / "b.txt") as tmp:
            tmp.write_text("y")
        write_gif(np.zeros((2, 4, 4, 3), dtype=np.uint8), tmp_path / "c.gif")  # was 0600 before
    finally:
        os.umask(old)
    for name in ("a.bin", "b.txt", "c.gif"):
        assert (tmp_path / name).stat().st_mode & 0o777 == mode, name


@pytest.mark.parametrize("exc", [RuntimeError("boom"), KeyboardInterrupt(), SystemExit(143)])
def test_atomic__an_exit_mid_write_leaves_the_old_file_and_no_temp(tmp_path: Path, exc: BaseException) -> None:
    target = tmp_path / "t.json"
    target.write_bytes(b"old")
    with pytest.raises(type(exc)):
        with atomic_file(target) as fh:
            fh.write(b"half of the new")
            raise exc
    assert target.read_bytes() == b"old"
    assert sorted(os.listdir(tmp_path)) == ["t.json"]
    with pytest.raises(type(exc)):
        with atomic_path(tmp_path / "new.txt") as tmp:
            tmp.write_text("half")
            raise exc
    assert sorted(os.listdir(tmp_path)) == ["t.json"]  # a new file never appears half-written


def test_atomic__a_failing_replace_keeps_the_old_content(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "t.bin"
    target.write_bytes(b"old")
    seen: list[str] = []

    def fail(src: str, dst: object) -> None:
        seen.append(Path(src).read_text())  # the complete new content sits in the temp file
        raise OSError(errno.EIO, "I/O error")

    monkeypatch.setattr(envs.atomic.os, "replace", fail)
    with pytest.raises(OSError, match="I/O error"):
        with atomic_file(target) as fh:
            fh.write(b"new")
    assert seen == ["new"] and target.read_bytes() == b"old" and os.listdir(tmp_path) == ["t.bin"]


def test_atomic__a_full_disk_is_one_disk_full_error_naming_the_file(tmp_path: Path) -> None:
    target = tmp_path / "t.bin"
    target.write_bytes(b"old")
    with pytest.raises(DiskFull, match=r"disk full while writing .*t\.bin"):
        with atomic_file(target):
            raise OSError(errno.ENOSPC, "No space left on device")
    assert target.read_bytes() == b"old" and os.listdir(tmp_path) == ["t.bin"]


def test_atomic__temp_names_and_their_targets(tmp_path: Path) -> None:
    names: list[str] = []
    with atomic_path(tmp_path / "clip.mp4", suffix=".mp4") as tmp:
        names.append(tmp.name)
        tmp.write_bytes(b"v")
    with atomic_path(tmp_path / "summary.md") as tmp:
        names.append(tmp.name)
        tmp.write_bytes(b"s")
    assert names[0].endswith(".tmp.mp4") and [temp_target(n) for n in names] == ["clip.mp4", "summary.md"]
    assert temp_target(".summary.md.abc123.tmp") == "summary.md"
    for other in (".mine.tmp", "summary.md.abc.tmp", ".x.md.abc.tmp.mp4", "summary.md"):
        assert temp_target(other) == "", other
