"""Scenarios: N distinct start cells and N distinct goal cells, every goal reachable.

Sampling draws from the largest connected free region of the layout, so every goal is
reachable from every start; explicit scenarios are validated cell by cell.
"""
from __future__ import annotations

import numpy as np

from envs.errors import BenchError
from envs.layouts import Layout


def main_region(layout: Layout) -> np.ndarray:
    """Free-cell indices of the largest 4-connected region; BenchError if there is no free cell."""
    comp = layout.components
    if comp.size == 0:
        h, w = layout.obstacles.shape
        raise BenchError(f"layout {layout.name!r} has no free cells (all {h}x{w} cells are obstacles)")
    labels, counts = np.unique(comp, return_counts=True)
    return np.flatnonzero(comp == labels[np.argmax(counts)])


def sample_scenarios(
    layout: Layout, n_robots: int, batch: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Seeded starts and goals, each (batch, n_robots) int64 cell indices.

    Starts are distinct, goals are distinct, and no robot starts on its own goal.
    """
    region = main_region(layout)
    if n_robots > len(region) or (n_robots == len(region) and n_robots == 1):
        raise BenchError(
            f"layout {layout.name!r} has {len(region)} connected free cells, too few for "
            f"{n_robots} robots (need at least {n_robots + (n_robots == 1)})"
        )
    starts = np.empty((batch, n_robots), np.int64)
    goals = np.empty((batch, n_robots), np.int64)
    for b in range(batch):
        starts[b] = rng.choice(region, size=n_robots, replace=False)
        g = rng.choice(region, size=n_robots, replace=False)
        # Re-draw goals that coincide with their own start (a derangement fix-up).
        for _ in range(100):
            same = g == starts[b]
            if not same.any():
                break
            idx = np.flatnonzero(same)
            if n_robots == 1:  # a lone robot: any other cell of the region
                g[0] = rng.choice(region[region != starts[b, 0]])
            elif len(idx) == 1:  # swap with a random other robot's goal
                j = int(rng.integers(n_robots - 1))
                j += j >= idx[0]
                g[[idx[0], j]] = g[[j, idx[0]]]
            else:
                g[idx] = g[np.roll(idx, 1)]
        goals[b] = g
    return starts, goals


def validate_scenario(
    layout: Layout, n_robots: int, starts: object, goals: object
) -> tuple[np.ndarray, np.ndarray]:
    """Explicit (row, col) lists -> (n_robots,) cell indices, or a clear BenchError."""
    out = []
    for what, cells in (("starts", starts), ("goals", goals)):
        arr = np.asarray(cells, dtype=np.int64)
        if arr.ndim != 2 or arr.shape[1] != 2:
            raise BenchError(f"{what}: expected a list of (row, col) pairs, got shape {arr.shape}")
        if arr.shape[0] != n_robots:
            raise BenchError(f"{what}: {arr.shape[0]} cells given for n_robots={n_robots}")
        idx = layout.to_index(arr, what=f"{what} cell")
        if len(np.unique(idx)) != n_robots:
            raise BenchError(f"{what}: cells must be distinct (two robots share a cell)")
        out.append(idx)
    s, g = out
    comp = layout.components
    bad = np.flatnonzero(comp[s] != comp[g])
    if len(bad):
        i = int(bad[0])
        raise BenchError(
            f"goal {tuple(map(int, layout.cells[g[i]]))} of robot {i} is unreachable from its "
            f"start {tuple(map(int, layout.cells[s[i]]))} in layout {layout.name!r}"
        )
    return s, g
