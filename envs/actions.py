"""The discrete control set U = {Up, Down, Left, Right, Wait} of the paper (Sec. II)."""
from __future__ import annotations

from enum import IntEnum

import numpy as np


class Action(IntEnum):
    """A robot's five actions U (|U| = 5): a move one cell up, down, left, right, or wait."""

    UP = 0
    DOWN = 1
    LEFT = 2
    RIGHT = 3
    WAIT = 4


N_ACTIONS = 5
WAIT = int(Action.WAIT)
# (d_row, d_col) per action, indexed by Action.
DELTAS = np.array([(-1, 0), (1, 0), (0, -1), (0, 1), (0, 0)], dtype=np.int64)
