"""The distance stores (all-pairs table, on-disk copy, bounded per-goal fields) agree exactly.

Runtime: about 3 s.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from envs.distances import UNREACHABLE, DistanceCache
from envs.layouts import Layout, from_ascii


def random_layout(seed: int, h: int, w: int, density: float) -> Layout:
    rng = np.random.default_rng(seed)
    obstacles = rng.random((h, w)) < density
    obstacles[0, 0] = False
    return Layout(f"rand{seed}", obstacles)


def lazy_fields(layout: Layout, goals: np.ndarray) -> np.ndarray:
    """The plain path: per-goal BFS fields, no table (bound 0 bytes)."""
    return DistanceCache(layout, max_bytes=0).fields(goals)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_table_fields__equal_per_goal_bfs_fields_including_unreachable(seed: int) -> None:
    layout = random_layout(seed, 17, 23, 0.35)  # dense: walls cut off pockets
    goals = np.random.default_rng(seed).choice(layout.n_free, size=40)
    table = DistanceCache(layout, max_bytes=10**9)
    assert table.use_table
    want = lazy_fields(layout, goals)
    assert (want == UNREACHABLE).any()  # the case the int16 sentinel must map back
    got = table.fields(goals)
    assert got.dtype == np.int32
    np.testing.assert_array_equal(got, want)


def test_table__is_written_once_then_memory_mapped_by_the_next_process(tmp_path: Path,
                                                                      monkeypatch) -> None:
    layout = random_layout(7, 40, 40, 0.2)  # >= 1024 free cells: kept on disk
    assert layout.n_free >= 1024
    goals = np.arange(0, layout.n_free, 97)
    first = DistanceCache(layout, directory=tmp_path, max_bytes=10**9).fields(goals)
    files = list(tmp_path.glob("dist-*.npy"))
    assert len(files) == 1
    again = DistanceCache(layout, directory=tmp_path, max_bytes=10**9)
    monkeypatch.setattr(again, "_build_table", lambda: pytest.fail("table rebuilt instead of loaded"))
    np.testing.assert_array_equal(again.fields(goals), first)
    assert isinstance(again.table(), np.memmap)
    np.testing.assert_array_equal(first, lazy_fields(layout, goals))


def test_table__a_corrupt_or_wrong_file_is_rebuilt(tmp_path: Path) -> None:
    layout = random_layout(8, 40, 40, 0.2)
    goals = np.arange(0, layout.n_free, 89)
    want = lazy_fields(layout, goals)
    DistanceCache(layout, directory=tmp_path, max_bytes=10**9).table()
    (path,) = tmp_path.glob("dist-*.npy")
    wrong = np.load(path).copy()
    wrong[0] += 1  # plausible but wrong numbers
    np.save(path, wrong)
    np.testing.assert_array_equal(DistanceCache(layout, directory=tmp_path, max_bytes=10**9).fields(goals), want)
    path.write_bytes(path.read_bytes()[:1000])  # truncated
    np.testing.assert_array_equal(DistanceCache(layout, directory=tmp_path, max_bytes=10**9).fields(goals), want)
    raw = np.load(path)[goals].astype(np.int32)  # replaced by a good copy (-1: no path)
    np.testing.assert_array_equal(np.where(raw < 0, UNREACHABLE, raw), want)


def test_per_goal_fields__stay_within_the_memory_bound_and_stay_exact() -> None:
    layout = random_layout(3, 30, 30, 0.25)
    per_field = 4 * layout.n_free
    cache = DistanceCache(layout, max_bytes=10 * per_field)
    assert not cache.use_table
    rng = np.random.default_rng(0)
    full = DistanceCache(layout, max_bytes=10**9)
    for _ in range(6):
        goals = rng.choice(layout.n_free, size=7)
        np.testing.assert_array_equal(cache.fields(goals), full.fields(goals))
        assert len(cache._fields) <= 10
    goals = rng.choice(layout.n_free, size=25, replace=False)  # more than the bound: all kept for the call
    np.testing.assert_array_equal(cache.fields(goals), full.fields(goals))


def test_table__is_not_used_above_the_memory_bound() -> None:
    layout = from_ascii("....\n.@@.\n....")
    assert not DistanceCache(layout, max_bytes=layout.n_free ** 2 * 2 - 1).use_table
    assert DistanceCache(layout, max_bytes=layout.n_free ** 2 * 2).use_table
