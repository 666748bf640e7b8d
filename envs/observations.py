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
        self._pairs: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}  # see _pair_index
        self._use_pairs: dict[tuple, bool] = {}
        # Window lookup for the pair writer: padded-grid index differences d = center[q] -
        # center[p] with q in p's window are exactly ``offsets`` (a column offset |dc| <=
        # W - 1 cannot alias one of -k..k because the padded width is W + 2k), so
        # _slot[d + _shift] - 1 is the window slot of q, or -1 (outside the window, the
        # observer's own cell, and both clipped ends).
        span = int(self.offsets.max())
        self._shift = span + 1
        slot = np.zeros(2 * span + 3, dtype=np.int64)  # slot + 1, 0 where unseen
        slot[self.offsets + self._shift] = np.arange(1, self.offsets.size + 1)
        slot[self._shift] = 0  # a robot on the observer's cell (possible off the floor)
        self._slot = slot
        self._off_floor = 2 * self.pad_obs.size + slot.size  # beyond every window: clipped to 0

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
        """Write the robot channel of ``__call__``, flattened, into ``out`` (B, N, P), by
        the cheaper of two writers with identical output (``use_pairs``)."""
        n = self.core.pos.shape[1]
        if self.use_pairs(groups):
            out[...] = 0.0
            obs, marks = self._robots_by_pairs(groups)
            out[obs // n, obs % n, marks] = 1.0
        else:
            self._robots_by_gather(out, groups)

    def use_pairs(self, groups: np.ndarray | None) -> bool:
        """Whether ``_robots_by_pairs`` handles fewer elements than ``_robots_by_gather``:
        the ordered pairs of distinct robots of one group, per episode, against the N P
        window cells (Z = 4 groups of 25 robots, k = 5: 2,400 against 12,100). Cached."""
        n = self.core.pos.shape[1]
        key = (n, None if groups is None else np.asarray(groups).tobytes())
        hit = self._use_pairs.get(key)
        if hit is None:
            sizes = np.array([n]) if groups is None else np.bincount(np.asarray(groups))
            pairs = int((sizes * (sizes - 1)).sum())
            hit = self._use_pairs[key] = pairs <= n * self.offsets.size
        return hit

    def _pair_index(self, groups: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """(M,) observer and (M,) other-robot indices into the flat (B N) robots of every
        ordered pair of distinct robots of one group in one episode (static; cached)."""
        b, n = self.core.pos.shape
        key = (b, n, None if groups is None else np.asarray(groups).tobytes())
        pairs = self._pairs.get(key)
        if pairs is None:
            g = np.zeros(n, np.int64) if groups is None else np.asarray(groups)
            same = g[:, None] == g[None, :]
            np.fill_diagonal(same, False)
            i, j = np.nonzero(same)
            first = (np.arange(b, dtype=np.int64) * n)[:, None]
            pairs = self._pairs[key] = ((first + i).reshape(-1), (first + j).reshape(-1))
        return pairs

    def _robots_by_pairs(self, groups: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """(K,) flat observer index and (K,) window slot of each robot seen by another.

        For every ordered pair (p, q) of one group: q is marked in p's window if q is on
        the floor and within the window, never on p's own slot (the centre)."""
        core = self.core
        obs, other = self._pair_index(groups)
        center = self.center.take(core.pos.reshape(-1))  # (B N,)
        shifted = center + self._shift
        occ = core.occupying.reshape(-1)
        if not occ.all():
            shifted[~occ] += self._off_floor
        slot = self._slot.take(shifted.take(other) - center.take(obs), mode="clip")
        seen = slot.nonzero()[0]
        return obs.take(seen), slot.take(seen) - 1

    def _robots_by_gather(self, out: np.ndarray, groups: np.ndarray | None) -> None:
        """The robot channel by one gather of every (B, N) window from a marked grid."""
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

    [state_features (11), local patch (2 (2k+1)^2)], written into one new buffer: the
    state columns in place (``state_features_into``), the shelf channel from a per-free-
    cell table and the robot channel by ``PatchExtractor``'s cheaper writer; the same
    numbers as ``np.concatenate([state_features, patch(groups)])``
    (tests/envs/test_observations.py).
    """
    b, n = core.pos.shape
    p = patch.offsets.size
    width = STATE_SIZE + 2 * p
    out = np.empty((b, n, width), dtype=np.float32)
    state_features_into(core, out[..., :STATE_SIZE])
    out[..., STATE_SIZE:STATE_SIZE + p] = patch.shelf_table()[core.pos]
    robots = out[..., STATE_SIZE + p:]
    if patch.use_pairs(groups):
        robots[...] = 0.0
        obs, slots = patch._robots_by_pairs(groups)
        out.reshape(-1)[obs * width + (STATE_SIZE + p) + slots] = 1.0
    else:
        patch._robots_by_gather(robots, groups)
    return out


def state_features_into(core: WarehouseCore, out: np.ndarray) -> None:
    """Write ``state_features(core)`` into ``out`` (B, N, 11) float32 (the same numbers,
    with fewer temporaries)."""
    layout = core.layout
    h, w = layout.shape
    scale = np.array([h, w], dtype=np.float32)
    cells = layout.float_cells
    rc = cells[core.pos]  # (B, N, 2); fancy indexing: take(axis=0) is slower for short rows
    np.divide(rc, scale, out=out[..., 0:2])
    np.subtract(cells[core.goal], rc, out=out[..., 2:4])
    np.divide(out[..., 2:4], scale, out=out[..., 2:4])
    np.divide(np.minimum(core.dist, h * w), float(h + w), out=out[..., 4])  # in float64
    out[..., 5] = core.done
    nxt = layout.next_cell[core.pos]  # (B, N, 5)
    np.subtract(core.dist[..., None], core.distances_to_goal(nxt), out=out[..., 6:6 + N_ACTIONS])


STATE_SIZE = 2 + 2 + 1 + 1 + N_ACTIONS  # columns of ``state_features``


def feature_size(radius: int) -> int:
    return STATE_SIZE + 2 * (2 * radius + 1) ** 2
