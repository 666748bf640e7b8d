"""Per-robot observation features over the static map, vectorized over (B, N).

Shared by the PettingZoo adapter and every learned method's encoder (one definition):

* ``action_progress``: for each action, the decrease of the shortest-path distance to
  the robot's goal it would give (-1, 0 or +1; 0 for Wait and blocked moves);
* ``local_patch``: a (2k+1)^2 window around each robot with one channel of shelves/walls
  and one channel of other robots (optionally only those in a mask, e.g. same group);
* ``robot_features``: a flat, fixed-size vector per robot assembled from the above plus
  normalized position, goal offset and distance, so any N uses the same network.
"""
from __future__ import annotations

import numpy as np

from envs.actions import N_ACTIONS
from envs.core import WarehouseCore


def action_progress(core: WarehouseCore) -> np.ndarray:
    """(B, N, 5) float32: D(p, g) - D(move(p, a), g) for each action a."""
    nxt = core.layout.next_cell[core.pos]  # (B, N, 5)
    d_next = core.distances_to_goal(nxt)
    return (core.dist[..., None] - d_next).astype(np.float32)


class PatchExtractor:
    """Extracts (B, N, 2, 2k+1, 2k+1) windows from a padded grid with one gather."""

    def __init__(self, core: WarehouseCore, radius: int) -> None:
        self.core, self.radius = core, radius
        h, w = core.layout.shape
        k = radius
        self.padded_shape = (h + 2 * k, w + 2 * k)
        pad_obs = np.ones(self.padded_shape, dtype=np.float32)
        pad_obs[k : k + h, k : k + w] = core.layout.obstacles
        self.pad_obs = pad_obs.reshape(-1)
        cells = core.layout.cells
        self.center = (cells[:, 0] + k) * self.padded_shape[1] + (cells[:, 1] + k)  # (F,)
        dr, dc = np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1), indexing="ij")
        self.offsets = (dr * self.padded_shape[1] + dc).reshape(-1)  # (P,)
        self._scratch: dict[tuple[str, int], np.ndarray] = {}

    def scratch(self, name: str, size: int, dtype: type) -> np.ndarray:
        """A zeroed flat work grid kept across steps. Callers write a few entries, read
        them, and zero exactly those entries again, so no full grid is allocated or
        zero-filled per step."""
        key = (name, size)
        grid = self._scratch.get(key)
        if grid is None:
            grid = self._scratch[key] = np.zeros(size, dtype=dtype)
        return grid

    def shelf_table(self) -> np.ndarray:
        """(F, P) float32 shelf/wall window of every free cell (static; built once)."""
        table = self._scratch.get(("shelf_table", 0))
        if table is None:
            table = self._scratch[("shelf_table", 0)] = self.pad_obs[self.center[:, None] + self.offsets]
        return table

    def robots_into(self, out: np.ndarray, groups: np.ndarray | None = None) -> None:
        """Write the robot channel of ``__call__``, flattened, into ``out`` (B, N, P)."""
        core = self.core
        b, n = core.pos.shape
        z = 1 if groups is None else int(groups.max()) + 1
        row = np.arange(b)[:, None] * z + (0 if groups is None else groups[None, :])  # (B, N)
        size = self.pad_obs.size
        grid = self.scratch("robots", b * z * size, np.float32)  # (B Z, padded cells), zeros
        occ = core.occupying
        centers = self.center[core.pos]  # (B, N)
        marks = np.broadcast_to(row, (b, n))[occ] * size + centers[occ]
        grid[marks] = 1.0
        np.take(grid, (row * size + centers)[..., None] + self.offsets, out=out, mode="clip")  # valid indices; clip: unbuffered
        grid[marks] = 0.0
        out[..., self.offsets.size // 2] = 0.0  # the robot itself

    def __call__(self, groups: np.ndarray | None = None) -> np.ndarray:
        """Shelves and robots around each robot; with ``groups`` ((N,) group index) the
        robot channel shows only robots of the observer's own group."""
        core = self.core
        b, n = core.pos.shape
        side = 2 * self.radius + 1
        idx = self.center[core.pos][..., None] + self.offsets  # (B, N, P)
        shelves = self.pad_obs[idx]
        z = 1 if groups is None else int(groups.max()) + 1
        row = np.arange(b)[:, None] * z + (0 if groups is None else groups[None, :])  # (B, N)
        row = np.broadcast_to(row, (b, n))
        size = self.pad_obs.size
        grid = self.scratch("robots", b * z * size, np.float32)  # (B Z, padded cells), zeros
        occ = core.occupying
        marks = row[occ] * size + self.center[core.pos[occ]]
        grid[marks] = 1.0
        robots = grid[(row * size)[..., None] + idx].reshape(b, n, -1)
        grid[marks] = 0.0
        robots[..., (side * side) // 2] = 0.0  # the robot itself
        return np.stack([shelves, robots], axis=2).reshape(b, n, 2, side, side)


def state_features(core: WarehouseCore) -> np.ndarray:
    """(B, N, 11) float32 what a robot knows of itself: position/shape (2), goal
    offset/shape (2), distance/(H+W) (1), done (1), action_progress (5)."""
    h, w = core.layout.shape
    scale = np.array([h, w], dtype=np.float32)
    rc = core.layout.cells[core.pos].astype(np.float32)  # (B, N, 2)
    grc = core.layout.cells[core.goal].astype(np.float32)
    return np.concatenate([
        rc / scale,
        (grc - rc) / scale,
        (np.minimum(core.dist, h * w) / float(h + w))[..., None].astype(np.float32),
        core.done[..., None].astype(np.float32),
        action_progress(core),
    ], axis=-1)


def robot_features(
    core: WarehouseCore, patch: PatchExtractor, groups: np.ndarray | None = None
) -> np.ndarray:
    """(B, N, F_obs) float32 per-robot features; see ``feature_size``.

    [state_features (11), local patch (2 (2k+1)^2)], written into one buffer: the shelf
    channel comes from a per-free-cell table and the robot channel from one gather, the
    same numbers as ``np.concatenate([state_features, patch(groups)])``
    (tests/envs/test_observations.py).
    """
    b, n = core.pos.shape
    p = patch.offsets.size
    out = np.empty((b, n, STATE_SIZE + 2 * p), dtype=np.float32)
    out[..., :STATE_SIZE] = state_features(core)
    out[..., STATE_SIZE:STATE_SIZE + p] = patch.shelf_table()[core.pos]
    patch.robots_into(out[..., STATE_SIZE + p:], groups)
    return out


STATE_SIZE = 2 + 2 + 1 + 1 + N_ACTIONS  # columns of ``state_features``


def feature_size(radius: int) -> int:
    return STATE_SIZE + 2 * (2 * radius + 1) ** 2
