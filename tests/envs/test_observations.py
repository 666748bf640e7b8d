"""Observation features on hand examples: action progress and local patches."""
from __future__ import annotations

import numpy as np

from envs.channel import group_assignment
from envs.config import EnvConfig
from envs.core import WarehouseCore
from envs.layouts import from_ascii
from envs.observations import PatchExtractor, action_progress, feature_size, robot_features
from envs.scenarios import validate_scenario


def make_core(floor: str, starts: list, goals: list, groups: int = 1) -> WarehouseCore:
    layout = from_ascii(floor)
    core = WarehouseCore(EnvConfig.make(n_robots=len(starts), groups=groups), layout=layout)
    s, g = validate_scenario(layout, len(starts), starts, goals)
    core.reset(s[None], g[None])
    return core


def test_action_progress_is_the_shortest_path_gain_of_each_action() -> None:
    core = make_core("...\n.@.\n...", [(0, 0), (0, 2)], [(2, 2), (0, 0)])
    prog = action_progress(core)
    assert prog.shape == (1, 2, 5)
    assert prog.dtype == np.float32
    #                          Up  Down Left Right Wait
    assert prog[0, 0].tolist() == [0, 1, 0, 1, 0]  # off-grid moves gain nothing
    assert prog[0, 1].tolist() == [0, -1, 1, 0, 0]  # Down walks away around the shelf


def test_action_progress_follows_the_robot_after_a_step() -> None:
    core = make_core("...\n.@.\n...", [(0, 0)], [(2, 2)])
    core.step(np.array([[3]]))  # Right to (0, 1): only Right gets closer now
    assert action_progress(core)[0, 0].tolist() == [0, 0, -1, 1, 0]


FLOOR = ".@..\n....\n..@."
# Robot i is in group i mod 2: robots 0 and 2 in group 0, robot 1 in group 1.
STARTS = [(0, 0), (1, 1), (1, 0)]
GOALS = [(2, 3), (0, 3), (2, 0)]


def test_patch_shows_shelves_and_the_outside_as_blocked() -> None:
    core = make_core(FLOOR, STARTS, GOALS, groups=2)
    patch = PatchExtractor(core, radius=1)()
    assert patch.shape == (1, 3, 2, 3, 3)
    assert patch[0, 0, 0].tolist() == [[1, 1, 1], [1, 0, 1], [1, 0, 0]]
    assert patch[0, 1, 0].tolist() == [[0, 1, 0], [0, 0, 0], [0, 0, 1]]


def test_patch_robot_channel_shows_other_robots_not_the_observer() -> None:
    core = make_core(FLOOR, STARTS, GOALS, groups=2)
    patch = PatchExtractor(core, radius=1)()
    assert patch[0, 0, 1].tolist() == [[0, 0, 0], [0, 0, 0], [0, 1, 1]]
    assert patch[0, 1, 1].tolist() == [[1, 0, 0], [1, 0, 0], [0, 0, 0]]
    assert patch[0, 2, 1].tolist() == [[0, 1, 0], [0, 0, 1], [0, 0, 0]]


def test_group_filtered_patch_shows_only_robots_of_the_observers_group() -> None:
    core = make_core(FLOOR, STARTS, GOALS, groups=2)
    patch = PatchExtractor(core, radius=1)(group_assignment(3, 2))
    assert patch[0, 0, 1].tolist() == [[0, 0, 0], [0, 0, 0], [0, 1, 0]]  # robot 2 only
    assert patch[0, 1, 1].tolist() == [[0, 0, 0], [0, 0, 0], [0, 0, 0]]  # alone in group 1
    assert patch[0, 2, 1].tolist() == [[0, 1, 0], [0, 0, 0], [0, 0, 0]]  # robot 0 only
    np.testing.assert_array_equal(patch[:, :, 0], PatchExtractor(core, 1)()[:, :, 0])


def test_patch_hides_robots_that_left_the_floor() -> None:
    # Robot 0 starts on its goal, so under on_goal="remove" it is not on the floor.
    core = make_core(FLOOR, STARTS, [(0, 0), (0, 3), (2, 0)], groups=2)
    patch = PatchExtractor(core, radius=1)()
    assert patch[0, 1, 1].tolist() == [[0, 0, 0], [1, 0, 0], [0, 0, 0]]


def test_robot_features_have_the_advertised_size() -> None:
    core = make_core(FLOOR, STARTS, GOALS, groups=2)
    feats = robot_features(core, PatchExtractor(core, radius=2))
    assert feats.shape == (1, 3, feature_size(2))
    assert feats.dtype == np.float32
    # position / shape, then goal offset / shape, for robot 1 at (1, 1) with goal (0, 3).
    np.testing.assert_allclose(feats[0, 1, :4], [1 / 3, 1 / 4, -1 / 3, 2 / 4])


def test_robot_features__one_buffer_equals_the_plain_concatenation_over_a_batch() -> None:
    """The fused writer (shelf table + one gather into the output) against
    concatenate([state_features, patch(groups)]) on a batch of random episodes run for a
    while (robots finish and leave the floor), with and without the group mask."""
    from envs.layouts import load_layout
    from envs.observations import state_features
    from envs.scenarios import sample_scenarios

    layout = load_layout("tiny")
    rng = np.random.default_rng(3)
    b, n = 4, 8
    core = WarehouseCore(EnvConfig.make(n_robots=n, groups=3, layout="tiny"), layout=layout)
    core.reset(*sample_scenarios(layout, n, b, rng))
    groups = group_assignment(n, 3)
    for radius in (1, 2):
        fused, patch = PatchExtractor(core, radius), PatchExtractor(core, radius)  # own scratch grids
        for _ in range(25):
            for g in (None, groups):
                plain = np.concatenate([state_features(core), patch(g).reshape(b, n, -1)], axis=-1)
                np.testing.assert_array_equal(robot_features(core, fused, g), plain)
            core.step(rng.integers(0, 5, size=(b, n)))
    assert core.done.any() and (~core.occupying).any()  # finished robots were covered
