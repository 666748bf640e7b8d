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
        self._pairs: dict[tuple, tuple] = {}  # see _pair_plan
        self._ext: dict[int, np.ndarray] = {}  # (B N + 1,) padded-grid index, sentinel last
        # Window lookup for the pair writer: padded-grid index differences d = center[q] -
        # center[p] with q in p's window are exactly ``offsets`` (a column offset |dc| <=
        # W - 1 cannot alias one of -k..k because the padded width is W + 2k), so
        # _slot[d + _shift] - 1 is the window slot of q, or -1 (outside the window, the
        # observer's own cell, and both clipped ends).
        span = int(self.offsets.max())
        self._shift = span + 1
        # slot + 1, 0 where unseen
        slot = np.zeros(2 * span + 3, dtype=np.uint8 if self.offsets.size < 255 else np.int64)
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

    def cell_table(self) -> np.ndarray:
        """(F, 11 + 2 P) float32: the ``robot_features`` row of a robot alone on each
        free cell, as far as it depends on the cell: position / shape (columns 0:2), the
        shelf/wall window (11:11 + P); 0 elsewhere (static; built once)."""
        table = self._scratch.get(("cell_table", 0))
        if table is None:
            layout = self.core.layout
            p = self.offsets.size
            table = np.zeros((layout.n_free, STATE_SIZE + 2 * p), np.float32)
            table[:, :2] = layout.float_cells / layout.float_shape
            table[:, STATE_SIZE:STATE_SIZE + p] = self.pad_obs[self.center[:, None] + self.offsets]
            table = self._scratch[("cell_table", 0)] = table
        return table

    def shelf_table(self) -> np.ndarray:
        """(F, P) float32 view: the shelf/wall window of every free cell (``cell_table``'s
        columns 11:11 + P; the baselines' ``local_view_into`` gathers from it)."""
        return self.cell_table()[:, STATE_SIZE:STATE_SIZE + self.offsets.size]

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
        Z S^2 (observer, other) entries of the group table (S = largest group) against
        the N P window cells (Z = 4 groups of 25 robots, k = 5: 2,500 against 12,100)."""
        return self._pair_plan(groups)[3]

    def _pair_plan(self, groups: np.ndarray | None) -> tuple:
        """Static tables of the pair writer for the current batch shape and ``groups``
        (cached): ``members`` (B Z, S) flat robot index of each group's members, padded
        with the sentinel B N; ``observer`` (B Z S S,) flat index of the observer of each
        (observer, other) entry; a dict of per-row-width write bases; ``use_pairs``."""
        b, n = self.core.pos.shape
        key = (b, n, None if groups is None else np.asarray(groups).tobytes())
        plan = self._pairs.get(key)
        if plan is None:
            g = np.zeros(n, np.int64) if groups is None else np.asarray(groups)
            labels, sizes = np.unique(g, return_counts=True)
            size = int(sizes.max())
            one = np.full((len(labels), size), -1, dtype=np.int64)  # (Z, S) of one episode
            for z, label in enumerate(labels):
                one[z, : sizes[z]] = np.flatnonzero(g == label)
            first = (np.arange(b, dtype=np.int64) * n)[:, None, None]
            members = np.where(one >= 0, first + one, b * n).reshape(-1, size)  # (B Z, S)
            observer = np.broadcast_to(members[:, :, None], members.shape + (size,))
            observer = np.where(observer < b * n, observer, 0).reshape(-1)
            use = len(labels) * size * size <= n * self.offsets.size
            plan = self._pairs[key] = (members, observer, {}, use)
        return plan

    def _pair_slots(self, groups: np.ndarray | None, plan: tuple | None = None
                    ) -> tuple[np.ndarray, np.ndarray, tuple]:
        """(K,) entries of the pair table in which the other robot is seen, (K,) its
        window slot + 1 there, and the plan (``_pair_plan``).

        For every (observer p, other q) of one group: q is seen if it is on the floor and
        within p's window, never on p's own slot (the centre); the sentinel (padding) is
        far from every cell, so it is never seen and never sees. ``plan``: the
        ``_pair_plan(groups)`` if the caller has it."""
        core = self.core
        plan = self._pair_plan(groups) if plan is None else plan
        members = plan[0]
        bn = core.pos.size
        ext = self._ext.get(bn)
        if ext is None:
            ext = self._ext[bn] = np.full(bn + 1, 2 * self._off_floor, dtype=np.int64)
        self.center.take(core.pos.reshape(-1), out=ext[:bn])  # padded-grid index
        shifted = ext + self._shift
        occ = core.occupying.reshape(-1)
        if np.count_nonzero(occ) < bn:
            shifted[:bn][~occ] += self._off_floor
        obs_c = ext.take(members)  # (B Z, S)
        other_c = shifted.take(members)
        slot = self._slot.take(other_c[:, None, :] - obs_c[:, :, None], mode="clip").reshape(-1)
        seen = (slot != 0).nonzero()[0]  # faster than slot.nonzero() on integers
        return seen, slot.take(seen), plan

    def _robots_by_pairs(self, groups: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """(K,) flat observer index and (K,) window slot of each robot seen by another."""
        seen, slot, plan = self._pair_slots(groups)
        return plan[1].take(seen), slot - 1

    def robot_marks(self, groups: np.ndarray | None, width: int, col: int,
                    plan: tuple | None = None) -> np.ndarray:
        """Flat indices, into a C-contiguous (B, N, ``width``) array whose robot channel
        starts at column ``col``, of the 1s of ``_robots_by_pairs``."""
        seen, slot, plan = self._pair_slots(groups, plan)
        bases = plan[2]
        base = bases.get((width, col))
        if base is None:
            base = bases[(width, col)] = plan[1] * width + (col - 1)
        return base.take(seen) + slot

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
        # valid indices; clip: unbuffered
        np.take(grid, (row * size + centers)[..., None] + self.offsets, out=out, mode="clip")
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

    [state_features (11), local patch (2 (2k+1)^2)] in one new array: the rows of a
    per-free-cell table (position / shape, shelf channel, zeros), then the other state
    columns in place (``state_features_into``) and the 1s of the robot channel by
    ``PatchExtractor``'s cheaper writer; the same numbers as
    ``np.concatenate([state_features, patch(groups)])`` (tests/envs/test_observations.py).
    """
    p = patch.offsets.size
    out = patch.cell_table()[core.pos]  # a new (B, N, F_obs) array, robot channel 0
    state_features_into(core, out[..., :STATE_SIZE], position=False)
    plan = patch._pair_plan(groups)
    if plan[3]:  # use_pairs
        out.reshape(-1)[patch.robot_marks(groups, out.shape[-1], STATE_SIZE + p, plan)] = 1.0
    else:
        patch._robots_by_gather(out[..., STATE_SIZE + p:], groups)
    return out


def state_features_into(core: WarehouseCore, out: np.ndarray, position: bool = True) -> None:
    """Write ``state_features(core)`` into ``out`` (B, N, 11) float32 (the same numbers,
    with fewer temporaries); ``position=False`` leaves columns 0:2 (position / shape)."""
    layout = core.layout
    h, w = layout.shape
    scale = layout.float_shape
    rc = layout.float_cells[core.pos]  # (B, N, 2); fancy indexing: take(axis=0) is slower
    if position:
        np.divide(rc, scale, out=out[..., 0:2])
    np.subtract(core.goal_rc, rc, out=out[..., 2:4])
    np.divide(out[..., 2:4], scale, out=out[..., 2:4])
    np.divide(np.minimum(core.dist, h * w), float(h + w), out=out[..., 4])  # in float64
    out[..., 5] = core.done
    nxt = layout.next_cell[core.pos]  # (B, N, 5)
    np.subtract(core.dist[..., None], core.distances_to_goal(nxt), out=out[..., 6:6 + N_ACTIONS])


STATE_SIZE = 2 + 2 + 1 + 1 + N_ACTIONS  # columns of ``state_features``


def feature_size(radius: int) -> int:
    return STATE_SIZE + 2 * (2 * radius + 1) ** 2
