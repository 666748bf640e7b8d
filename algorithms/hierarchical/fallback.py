"""Per-robot fallback: only the offending robots wait (a variant of Algorithm 1, line 12).

The paper's filter executes joint Wait for the whole group when no candidate within
radius L and budget C_max is admissible (alg:safety_filter line 12). This variant keeps
the proposal of every robot that can keep it and makes the offending robots wait instead:
a moving robot offends if its move violates condition (1) or (4) of eq:safety_conditions,
or conflicts (2)/(3) with another robot of the group. A robot told to wait stays on its
cell, which can create new conflicts for robots moving into it, so the rule repeats until
no moving robot offends (at most n rounds; the waiting set only grows).

What it keeps of the paper's guarantee: in the result every *moving* robot satisfies
(1)-(4), and no two robots of the group conflict; waiting robots may sit inside a
neighbour's reachable set, exactly as under joint Wait. So one-step safety with true
positions (prop:one_step_safety) holds as it does for joint Wait: the neighbours' own
filters keep out of the cells of this group's robots.
"""
from __future__ import annotations

import numpy as np

from envs.actions import WAIT


def offenders_wait(next_cell: np.ndarray, move_valid: np.ndarray, pos: np.ndarray, occupies: np.ndarray,
                   controlled: np.ndarray, proposal: np.ndarray, blocked: np.ndarray) -> np.ndarray:
    """(G, n) controls: the proposal with offending robots set to Wait, repeated to a fixed point.

    next_cell, move_valid (F, 5) of the layout; pos (G, n) cells (any value on padding),
    occupies (G, n) robots on the floor, controlled (G, n) robots the group steers,
    proposal (G, n), blocked (G, F) union of the neighbours' reachable sets
    (``SafetyFilter.blocked_cells``). Uncontrolled robots wait.
    """
    g, n = pos.shape
    p = np.maximum(pos, 0)
    ctl = controlled & occupies
    act = np.where(ctl, proposal, WAIT)
    pair = occupies[:, :, None] & occupies[:, None, :] & ~np.eye(n, dtype=bool)
    rows = np.arange(g)[:, None]
    for _ in range(n + 1):
        nxt = next_cell[p, act]  # (G, n); Wait stays
        moving = ctl & (act != WAIT)
        unary = ~move_valid[p, act] | blocked[rows, nxt]  # (1), (4)
        conflict = ((nxt[:, :, None] == nxt[:, None, :])  # (2)
                    | ((nxt[:, :, None] == p[:, None, :]) & (nxt[:, None, :] == p[:, :, None]))) & pair  # (3)
        offend = moving & (unary | conflict.any(-1))
        if not offend.any():
            break
        act = np.where(offend, WAIT, act)
    return act
