"""Optuna studies: ``bench tune`` tunes a learned method by one protocol for every method.

Built for the hierarchical method's open design choices (SPEC 6): |R_z| (``ref_size``), L
(``search_radius``), optionally C_max; any learned method's parameters with ``--method`` and
``--param`` (the same budget and protocol for each), for a chosen N, p and layout.
``studies/cli.py`` is the command; docs/studies.md the guide.

May import: envs, algorithms, bench, reports (the top layer of .importlinter).
"""
from __future__ import annotations

from pathlib import Path

DEFAULT_ROOT = Path("results") / "studies"  # one folder per study: journal, trials, report
