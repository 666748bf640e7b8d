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


def test_robot_channel__pair_and_gather_writers_equal_the_plain_patch() -> None:
    """Both writers of the robot channel (``_robots_by_pairs``, ``_robots_by_gather``),
    whichever ``use_pairs`` picks, against ``PatchExtractor.__call__`` bit for bit: robots
    at the map's edges, finished robots off the floor (``on_goal="remove"``, one standing
    on another's cell) or staying, with and without the group mask, B = 1 and 3."""
    from envs.layouts import load_layout
    from envs.scenarios import sample_scenarios

    layout = load_layout("wh20")
    rng = np.random.default_rng(5)
    n = 20
    groups = group_assignment(n, 4)
    shared = 0
    for on_goal in ("remove", "stay"):
        for b in (1, 3):
            core = WarehouseCore(EnvConfig.make(n_robots=n, groups=4, on_goal=on_goal), layout)
            core.reset(*sample_scenarios(layout, n, b, rng))
            for radius in (0, 1, 5):
                patch = PatchExtractor(core, radius)
                p = patch.offsets.size
                for _ in range(15):
                    for g in (None, groups):
                        want = patch(g)[:, :, 1].reshape(b, n, p)
                        by_gather = np.full((b, n, p), 7.0, np.float32)
                        patch._robots_by_gather(by_gather, g)
                        by_pairs = np.zeros((b, n, p), np.float32)
                        obs, slots = patch._robots_by_pairs(g)
                        by_pairs[obs // n, obs % n, slots] = 1.0
                        into = np.full((b, n, p), 7.0, np.float32)
                        patch.robots_into(into, g)
                        for got in (by_gather, by_pairs, into):
                            assert got.tobytes() == want.tobytes()
                        assert robot_features(core, patch, g)[..., -p:].tobytes() == want.tobytes()
                    for e in range(b):  # an off-floor robot on an on-floor robot's cell
                        occ = core.occupying[e]
                        shared += bool(np.isin(core.pos[e][~occ], core.pos[e][occ]).any())
                    core.step(rng.integers(0, 5, size=(b, n)))
            assert core.done.any()
    assert shared
    # radius 0 (P = 1) uses the gather, radius 5 the pairs.
    assert not PatchExtractor(core, 0).use_pairs(groups) and PatchExtractor(core, 5).use_pairs(groups)
