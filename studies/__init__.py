"""Optuna studies of the hierarchical method's open design choices (SPEC 6, issue #7).

``bench tune`` (studies/cli.py) searches |R_z| (``ref_size``) and L (``search_radius``),
optionally C_max, for a chosen N, p and layout; see docs/studies.md.

May import: envs, algorithms, bench, reports (the top layer of .importlinter).
"""
from __future__ import annotations

from pathlib import Path

DEFAULT_ROOT = Path("results") / "studies"  # one folder per study: journal, trials, report
