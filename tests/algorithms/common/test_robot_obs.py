"""The per-robot local view every learned method observes: nearby robots, on hand examples.

Runtime < 1 s.
"""
from __future__ import annotations

import numpy as np

from algorithms.common.robot_obs import local_view, local_view_size, robots_on_target_index
from envs.actions import DELTAS, Action
from envs.config import EnvConfig
from envs.core import WarehouseCore
from envs.layouts import from_ascii
from envs.observations import PatchExtractor, robot_features
from envs.scenarios import validate_scenario

FLOOR = ".......\n.......\n.......\n......."


def make_core(starts: list, goals: list, groups: int = 1) -> WarehouseCore:
    layout = from_ascii(FLOOR)
    core = WarehouseCore(EnvConfig.make(n_robots=len(starts), groups=groups, loss_p=0.0), layout)
    s, g = validate_scenario(layout, len(starts), starts, goals)
    core.reset(s[None], g[None])
    return core


def robot_patch(view: np.ndarray, radius: int = 1) -> np.ndarray:
    """(B, N, side, side) robot channel of a local view."""
    side = 2 * radius + 1
    start = 11 + side * side
    return view[..., start : start + side * side].reshape(*view.shape[:2], side, side)


def test_local_view__shows_every_nearby_robot_at_its_current_cell() -> None:
    # Robot 0 at (1, 1); robot 1 right of it; robot 2 diagonal up-left; robot 3 out of range.
    core = make_core([(1, 1), (1, 2), (0, 0), (3, 5)], [(3, 0), (3, 1), (3, 2), (0, 6)], groups=2)
    view = local_view(core, PatchExtractor(core, 1))
    assert view.shape == (1, 4, local_view_size(1))
    seen = robot_patch(view)
    assert seen[0, 0].tolist() == [[1, 0, 0], [0, 0, 1], [0, 0, 0]]  # itself blanked
    assert seen[0, 1].tolist() == [[0, 0, 0], [1, 0, 0], [0, 0, 0]]
    assert seen[0, 3].sum() == 0
    # Robots 1 and 3 are in another group (i mod 2) than robot 0: the baselines see them,
    # the hierarchical local policy's patch (same group only, Proposition 1) does not.
    same_group = robot_patch(robot_features(core, PatchExtractor(core, 1), np.arange(4) % 2))
    assert same_group[0, 0].tolist() == [[1, 0, 0], [0, 0, 0], [0, 0, 0]]


def test_local_view__drops_robots_that_left_the_floor() -> None:
    core = make_core([(1, 1), (1, 2)], [(3, 0), (1, 3)])
    core.step(np.array([[int(Action.WAIT), int(Action.RIGHT)]]))  # robot 1 arrives, is removed
    assert core.done[0, 1]
    assert robot_patch(local_view(core, PatchExtractor(core, 1)))[0, 0].sum() == 0


def test_robots_on_target_index__is_the_robot_patch_at_each_action_target() -> None:
    core = make_core([(1, 1), (0, 1), (2, 1), (1, 0), (1, 2), (3, 6)],
                     [(3, 0), (3, 1), (3, 2), (3, 3), (3, 4), (0, 6)])
    for radius in (1, 2):
        phi = local_view(core, PatchExtractor(core, radius))[..., robots_on_target_index(radius)[0]]
        cells = core.layout.cells
        target = cells[core.pos][:, :, None, :] + DELTAS  # (B, N, 5, 2)
        occupied = (cells[core.pos][:, None, None, :, :] == target[:, :, :, None, :]).all(-1)
        expected = occupied & ~np.eye(6, dtype=bool)[None, :, None, :]  # not the robot itself
        assert np.array_equal(phi, expected.sum(-1)), radius
        assert phi[0, 0, :4].tolist() == [1, 1, 1, 1]  # robot 0 is boxed in on all sides
