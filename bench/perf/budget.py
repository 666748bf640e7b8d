"""The budget of a full-size cell, which the speed suites scale their timings to: the
``Cell`` field defaults (bench/design/cells.py), i.e. what a grid gets where it sets
nothing. One home, so the suites follow the defaults if they change.

May import: bench.design.
"""
from __future__ import annotations

from typing import Any

from bench.design.cells import Cell

__all__ = ["C_MAX", "EPISODES", "EVAL_EPISODES", "HORIZON", "SEARCH_RADIUS"]


def _default(field: str) -> Any:
    return Cell.model_fields[field].default


EPISODES: int = _default("episodes")  # training episodes of a cell
HORIZON: int = _default("horizon")  # maximum episode length T
EVAL_EPISODES: int = _default("eval_episodes")  # evaluation episodes per execution mode
SEARCH_RADIUS: int = _default("search_radius")  # safety-filter search radius L
C_MAX: int = _default("c_max")  # safety-filter candidate budget C_max
