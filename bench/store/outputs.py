"""Output paths a user names (``--out`` of ``bench report`` and ``bench replay``) never
replace a file the bench did not write (D7/D9, SPEC 7).

* ``report --out DIR``: DIR may be new, empty, or a report folder the bench built (its
  ``index.md`` starts with ``# Report: ``); an existing file, or a folder holding other
  files, is refused with one line (``--force`` writes into such a folder anyway; a file is
  never turned into a folder). The default ``RUN/report/`` is the bench's own.
* ``replay --out PATH``: a new path; an existing file only with ``--force``. The default
  path (``RUN/replays/<cell>-ep<K>...``) is the bench's own and is rebuilt in place.
"""
from __future__ import annotations

import re
from pathlib import Path

from envs.errors import BenchError

REPORT_MARK = "# Report: "  # first line of every index.md the report writes (reports/pages/index.py)


# Names a report writes (reports/build.py, reports/matrix.py), so that a folder left by an
# interrupted report (index.md and index.html are written last) is still recognized as the bench's.
REPORT_NAMES = re.compile(
    r"(fig[123]_\w+|table1_safety|summary|success_by_mode|progress|claims(_table)?|calibration|ablation"
    r"|matrix\w*)\.(png|pdf|txt|md|csv|tex|json|html)|studies|replays|\..+\.tmp")


def is_bench_report(folder: Path) -> bool:
    """Whether ``folder`` is a report the bench wrote (its index.md, or only report names)."""
    try:
        with open(folder / "index.md", encoding="utf-8") as fh:
            if fh.readline().startswith(REPORT_MARK):
                return True
    except (OSError, UnicodeDecodeError):
        pass
    return all(REPORT_NAMES.fullmatch(p.name) for p in folder.iterdir())


def check_report_out(out: Path, force: bool) -> None:
    """BenchError unless the report may be written into folder ``out`` (see above)."""
    if out.is_symlink() and not out.exists():
        raise BenchError(f"--out {str(out)!r} is a dangling symlink; choose another --out")
    if out.exists() and not out.is_dir():
        raise BenchError(f"--out {str(out)!r} is an existing file, not a folder; the report is a folder "
                         "of files: choose a new or empty folder")
    if not out.is_dir() or force or is_bench_report(out) or not any(out.iterdir()):
        return
    raise BenchError(f"--out {str(out)!r} holds files the bench did not write (no report index.md there); "
                     "the report would overwrite index.md, index.html and more: choose a new or empty "
                     "folder, or pass --force")


def check_replay_out(out: Path, default: bool, force: bool) -> None:
    """BenchError unless the replay may be written to file ``out`` (see above)."""
    if out.is_dir():
        raise BenchError(f"--out {str(out)!r} is a folder; give the path of the {out.suffix or 'GIF'} file to write")
    if (out.exists() or out.is_symlink()) and not (default or force):
        raise BenchError(f"--out {str(out)!r} already exists and `bench replay` did not write it there; "
                         "choose another path, or pass --force to replace it")
