"""The report's file writers: text, a figure as PNG + PDF (+ caption), a copied file.

Every write goes through ``envs.atomic`` (temp file, fsync, rename; permissions from the
umask; a full disk is one ``DiskFull`` line naming the file, the old file kept), so an
interrupted rebuild never leaves a half-written file. The run report (``reports.build``,
``reports.matrix``) and the study report (``studies.report``) write with these.

May import: envs, reports.figures.plotting.
"""
from __future__ import annotations

import shutil
from pathlib import Path

from matplotlib.figure import Figure

from envs.atomic import atomic_path
from reports.figures.plotting import DPI

__all__ = ["copy_file", "save_figure", "write_text"]


def write_text(path: Path, text: str) -> Path:
    """``text`` as UTF-8 into ``path``; returns ``path``."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path


def copy_file(src: Path, dst: Path) -> Path:
    """``src``'s bytes into ``dst``; returns ``dst``."""
    with atomic_path(dst) as tmp:
        shutil.copyfile(src, tmp)
    return dst


def save_figure(fig: Figure, stem: Path, caption: str = "") -> list[Path]:
    """``stem``.png (200 dpi) and ``stem``.pdf; with a caption, also ``stem``.txt holding it
    and the caption in the files' metadata (PDF Subject, PNG Description); the PDF has no
    creation date, so rebuilding a report gives the same bytes."""
    keys = {"png": "Description", "pdf": "Subject"}
    # No creation date in the PDF: a rebuilt report is byte-identical (tests/reproduction).
    fixed: dict[str, dict[str, str | None]] = {"png": {}, "pdf": {"CreationDate": None}}
    out = []
    for fmt in ("png", "pdf"):
        path = stem.with_suffix(f".{fmt}")
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format=fmt, dpi=DPI, metadata={**fixed[fmt], **({keys[fmt]: caption} if caption else {})})
        out.append(path)
    if caption:
        out.append(write_text(stem.with_suffix(".txt"), caption + "\n"))
    return out
