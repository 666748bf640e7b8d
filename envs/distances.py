"""Shortest-path (BFS) distance fields D(., g) on the grid, computed once per layout.

The paper's distance D in eq:reward is the grid shortest-path length, never Euclidean
(SPEC 2). Two stores, chosen per layout by size (docs/decisions/0010):

* **all-pairs table** (F, F) int16, ``table[g, c] = D(c, g)``, when it fits the memory
  bound (``WAREHOUSE_BENCH_DIST_TABLE_MB``, default 512 MB; the MovingAI map's 5,699
  cells take 65 MB). Computed once in blocks of goals by scipy's unweighted Dijkstra
  (= BFS, in C) and kept on disk under the cache directory (``WAREHOUSE_BENCH_CACHE``,
  default ``~/.cache/warehouse-marl-bench``) keyed by a hash of the obstacle grid, so
  every later process (a Ray worker, the next cell) memory-maps it instead of searching
  again. A missing, truncated or mismatching file is recomputed and replaced atomically.
* **per-goal fields** computed lazily for the goals a batch needs, for layouts whose
  table would exceed the bound; at most that many bytes of fields are kept (oldest
  dropped first).

Both give identical int32 fields (UNREACHABLE where no path exists).
"""
from __future__ import annotations

import hashlib
import os
import weakref
from pathlib import Path

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from envs.atomic import DiskFull, atomic_file
from envs.layouts import Layout

UNREACHABLE = np.iinfo(np.int32).max // 4
TABLE_FORMAT = 1  # bump when the on-disk table's meaning changes
_NO_PATH = -1  # int16 table entry of an unreachable cell
_BLOCK = 256  # goals per scipy call while building the table (bounds its float64 scratch)
_DISK_MIN_CELLS = 1024  # smaller tables are rebuilt in memory (milliseconds), never written


def cache_dir() -> Path:
    """Directory of the on-disk distance tables (``WAREHOUSE_BENCH_CACHE`` overrides)."""
    env = os.environ.get("WAREHOUSE_BENCH_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "warehouse-marl-bench"


def table_limit_bytes() -> int:
    """Largest all-pairs table kept in memory (``WAREHOUSE_BENCH_DIST_TABLE_MB``, MB)."""
    return int(float(os.environ.get("WAREHOUSE_BENCH_DIST_TABLE_MB", "512")) * 2**20)


def layout_key(layout: Layout) -> str:
    """Stable hash of the obstacle grid (names do not matter, cells do)."""
    h = hashlib.sha256(f"v{TABLE_FORMAT}:{layout.shape[0]}x{layout.shape[1]}:".encode())
    h.update(np.packbits(layout.obstacles).tobytes())
    return h.hexdigest()[:24]


class DistanceCache:
    """Distance fields of one layout: ``fields(goals)[k, c] = D(cell c, goals[k])``."""

    def __init__(self, layout: Layout, directory: Path | None = None,
                 max_bytes: int | None = None) -> None:
        self.layout = layout
        f = layout.n_free
        src = np.repeat(np.arange(f), 4)
        dst = layout.next_cell[:, :4].reshape(-1)
        keep = src != dst
        self._graph = csr_matrix(
            (np.ones(int(keep.sum()), dtype=np.float64), (src[keep], dst[keep])), shape=(f, f)
        )
        self._dir = directory
        self.max_bytes = table_limit_bytes() if max_bytes is None else int(max_bytes)
        # int16 holds every distance (< F <= 32767 cells) and the -1 sentinel.
        self.use_table = f * f * 2 <= self.max_bytes and f <= np.iinfo(np.int16).max
        self._table: np.ndarray | None = None
        self._fields: dict[int, np.ndarray] = {}

    # ------------------------------------------------------------------ BFS
    def _search(self, goals: list[int] | np.ndarray) -> np.ndarray:
        """(len(goals), F) float64 BFS distances (inf where unreachable)."""
        # The grid graph is symmetric, so distances *from* the goal equal distances to it.
        return shortest_path(self._graph, method="D", unweighted=True, indices=goals)

    def _build_table(self) -> np.ndarray:
        f = self.layout.n_free
        table = np.empty((f, f), dtype=np.int16)
        for lo in range(0, f, _BLOCK):
            d = self._search(np.arange(lo, min(lo + _BLOCK, f)))
            table[lo : lo + len(d)] = np.where(np.isfinite(d), d, _NO_PATH)
        return table

    def _table_ok(self, table: np.ndarray) -> bool:
        f = self.layout.n_free
        if table.shape != (f, f) or table.dtype != np.int16:
            return False
        probe = np.unique([0, f // 2, f - 1])  # spot-check rows against a fresh search
        d = self._search(probe)
        return bool(np.array_equal(table[probe], np.where(np.isfinite(d), d, _NO_PATH)))

    def table(self) -> np.ndarray:
        """The (F, F) int16 all-pairs table (-1: no path); loads or builds it once."""
        if self._table is not None:
            return self._table
        f = self.layout.n_free
        path = None
        if f >= _DISK_MIN_CELLS:
            directory = self._dir if self._dir is not None else cache_dir()
            path = directory / f"dist-{layout_key(self.layout)}-{f}.npy"
            try:
                table = np.load(path, mmap_mode="r")
                if self._table_ok(table):
                    self._table = table
                    return table
            except (OSError, ValueError, EOFError):
                pass  # missing or unreadable: rebuild below
        table = self._build_table()
        table.setflags(write=False)
        if path is not None:
            _atomic_save(path, table)
        self._table = table
        return table

    # -------------------------------------------------------------- queries
    def fields(self, goals: np.ndarray) -> np.ndarray:
        """(len(goals), F) int32 distances; UNREACHABLE where no path exists."""
        goals = np.asarray(goals, dtype=np.int64).reshape(-1)
        f = self.layout.n_free
        if not len(goals):
            return np.zeros((0, f), np.int32)
        if self.use_table:
            rows = self.table()[goals].astype(np.int32)
            rows[rows == _NO_PATH] = UNREACHABLE
            return rows
        uniq = [int(g) for g in np.unique(goals)]
        missing = [g for g in uniq if g not in self._fields]
        for g in uniq:  # least recently used first: move this call's goals to the end
            if g in self._fields:
                self._fields[g] = self._fields.pop(g)
        if missing:
            d = self._search(missing)
            d = np.where(np.isfinite(d), d, UNREACHABLE).astype(np.int32)
            for g, row in zip(missing, d, strict=True):
                row.setflags(write=False)
                self._fields[g] = row
            keep = max(self.max_bytes // (4 * f), len(uniq))
            for g in list(self._fields)[: max(len(self._fields) - keep, 0)]:
                del self._fields[g]  # never one this call needs (they are the newest)
        return np.stack([self._fields[int(g)] for g in goals])

    def field(self, goal: int) -> np.ndarray:
        return self.fields(np.array([goal]))[0]


def _atomic_save(path: Path, table: np.ndarray) -> None:
    """Write ``table`` as .npy atomically (envs/atomic.py); a read-only or full cache is skipped."""
    try:
        with atomic_file(path) as fh:
            np.save(fh, table)
    except (OSError, DiskFull):
        pass  # no writable cache: the table still serves this process


_CACHES: weakref.WeakKeyDictionary[Layout, DistanceCache] = weakref.WeakKeyDictionary()


def distance_cache(layout: Layout) -> DistanceCache:
    """The shared cache of a layout (one per process)."""
    cache = _CACHES.get(layout)
    if cache is None:
        cache = _CACHES[layout] = DistanceCache(layout)
    return cache
