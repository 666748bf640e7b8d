"""PatchExtractor's reused work grid gives exactly the plain (fresh zero grid) patches.

Runtime: under 1 s.
"""
from __future__ import annotations

import numpy as np

from envs.config import EnvConfig
from envs.core import WarehouseCore
from envs.layouts import preset
from envs.observations import PatchExtractor
from envs.scenarios import sample_scenarios


def plain_patch(patch: PatchExtractor, groups: np.ndarray | None) -> np.ndarray:
    """The unoptimized extractor: a new zero grid of every (episode, group) per call."""
    core = patch.core
    b, n = core.pos.shape
    side = 2 * patch.radius + 1
    idx = patch.center[core.pos][..., None] + patch.offsets
    shelves = patch.pad_obs[idx]
    z = 1 if groups is None else int(groups.max()) + 1
    row = np.broadcast_to(np.arange(b)[:, None] * z + (0 if groups is None else groups[None, :]), (b, n))
    grid = np.zeros((b * z, patch.pad_obs.size), dtype=np.float32)
    occ = core.occupying
    grid[row[occ], patch.center[core.pos[occ]]] = 1.0
    robots = grid[row[..., None], idx].reshape(b, n, -1)
    robots[..., (side * side) // 2] = 0.0
    return np.stack([shelves, robots], axis=2).reshape(b, n, 2, side, side)


def test_patch_extractor__equals_the_plain_extractor_step_after_step() -> None:
    layout = preset("wh20")
    rng = np.random.default_rng(0)
    for on_goal in ("remove", "stay"):
        core = WarehouseCore(EnvConfig.make(n_robots=20, groups=3, on_goal=on_goal), layout)
        core.reset(*sample_scenarios(layout, 20, 4, rng))
        patch = PatchExtractor(core, 2)
        groups = np.arange(20) % 3
        for _ in range(30):  # robots move, collide and leave: stale marks would show
            for g in (None, groups):
                np.testing.assert_array_equal(patch(g), plain_patch(patch, g))
            core.step(rng.integers(0, 5, size=(4, 20)))
            core.done |= rng.random((4, 20)) < 0.05  # some robots leave the floor
