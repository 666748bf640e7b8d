"""Shortest-path (BFS) distance fields D(., g) on the grid, cached per goal cell.

The paper's distance D in eq:reward is the grid shortest-path length, never Euclidean
(SPEC 2). Fields are computed in C by scipy's unweighted Dijkstra (= BFS) for all the
goals a batch needs at once and kept per layout.
"""
from __future__ import annotations

import weakref

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from envs.layouts import Layout

UNREACHABLE = np.iinfo(np.int32).max // 4


class DistanceCache:
    """Distance fields of one layout: ``fields(goals)[k, c] = D(cell c, goals[k])``."""

    def __init__(self, layout: Layout) -> None:
        self.layout = layout
        f = layout.n_free
        src = np.repeat(np.arange(f), 4)
        dst = layout.next_cell[:, :4].reshape(-1)
        keep = src != dst
        self._graph = csr_matrix(
            (np.ones(int(keep.sum()), dtype=np.float64), (src[keep], dst[keep])), shape=(f, f)
        )
        self._fields: dict[int, np.ndarray] = {}

    def fields(self, goals: np.ndarray) -> np.ndarray:
        """(len(goals), F) int32 distances; UNREACHABLE where no path exists."""
        goals = np.asarray(goals, dtype=np.int64).reshape(-1)
        missing = [int(g) for g in np.unique(goals) if int(g) not in self._fields]
        if missing:
            # The grid graph is symmetric, so distances *from* the goal equal distances to it.
            d = shortest_path(self._graph, method="D", unweighted=True, indices=missing)
            d = np.where(np.isfinite(d), d, UNREACHABLE).astype(np.int32)
            for g, row in zip(missing, d, strict=True):
                row.setflags(write=False)
                self._fields[g] = row
        return np.stack([self._fields[int(g)] for g in goals]) if len(goals) else np.zeros(
            (0, self.layout.n_free), np.int32
        )

    def field(self, goal: int) -> np.ndarray:
        return self.fields(np.array([goal]))[0]


_CACHES: weakref.WeakKeyDictionary[Layout, DistanceCache] = weakref.WeakKeyDictionary()


def distance_cache(layout: Layout) -> DistanceCache:
    """The shared cache of a layout (one per process)."""
    cache = _CACHES.get(layout)
    if cache is None:
        cache = _CACHES[layout] = DistanceCache(layout)
    return cache
