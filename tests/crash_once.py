"""Crash a worker once, whichever worker gets there first."""
from __future__ import annotations

import os


def first_claim(marker: str) -> bool:
    """True for exactly one caller across all processes: the one that creates ``marker``.

    The file is created with ``O_EXCL``, so two workers that reach it at the same moment cannot
    both see it missing (a check-then-create would let both crash).
    """
    try:
        os.close(os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:
        return False
    return True
