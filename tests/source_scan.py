"""One scanner for the tests that pin where a rule lives (the channel built only in envs/,
the Parquet rows read only by the run store, the loss rule called only where a loss
enters): every code line under some folders that matches a pattern, comments ignored."""
from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path


def code_matches(base: Path, folders: tuple[str, ...], pattern: re.Pattern[str],
                 skip: frozenset[str] = frozenset()) -> Iterator[tuple[str, int, str]]:
    """(path relative to ``base``, line number, code) of every line of the Python files under
    ``base / folder`` whose code (the line before any ``#``) matches ``pattern``; files
    named in ``skip`` are not read."""
    for folder in folders:
        for path in sorted((base / folder).rglob("*.py")):
            rel = path.relative_to(base).as_posix()
            if rel in skip:
                continue
            for k, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
                code = line.split("#", 1)[0]
                if pattern.search(code):
                    yield rel, k, code
