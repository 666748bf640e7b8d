"""Collision rules, goals, episode ends, reward terms and input errors of the batched core.

Every case is a hand-built ASCII floor with explicit (row, col) starts and goals and the
answer worked out by hand. Actions: 0 Up, 1 Down, 2 Left, 3 Right, 4 Wait.
"""
from __future__ import annotations

import numpy as np
import pytest

from envs.config import EnvConfig
from envs.core import StepResult, WarehouseCore
from envs.errors import BenchError
from envs.layouts import from_ascii
from envs.scenarios import sample_scenarios, validate_scenario

U, D, L, R, W = 0, 1, 2, 3, 4
OPEN_3X4 = "....\n....\n...."


def make_core(
    floor: str, starts: list[tuple[int, int]], goals: list[tuple[int, int]],
    on_goal: str = "remove", horizon: int = 50, **weights: float,
) -> WarehouseCore:
    layout = from_ascii(floor, name="hand")
    config = EnvConfig.make(
        n_robots=len(starts), groups=1, horizon=horizon, on_goal=on_goal, reward=weights or {}
    )
    core = WarehouseCore(config, layout=layout)
    s, g = validate_scenario(layout, len(starts), starts, goals)
    core.reset(s[None], g[None])
    return core


def step(core: WarehouseCore, *actions: int) -> StepResult:
    return core.step(np.array([actions], dtype=np.int64))


def positions(core: WarehouseCore) -> list[tuple[int, int]]:
    return [tuple(int(v) for v in core.layout.cells[c]) for c in core.pos[0]]


# Goals far away in the bottom row unless a test needs them elsewhere.
FAR = [(2, 0), (2, 1), (2, 2), (2, 3)]


def test_vertex_conflict_keeps_both_robots_in_place_and_flags_both() -> None:
    core = make_core(OPEN_3X4, [(0, 0), (0, 2)], FAR[:2])
    out = step(core, R, L)  # both want (0, 1)
    assert positions(core) == [(0, 0), (0, 2)]
    assert out.collision[0].tolist() == [True, True]
    assert out.invalid[0].tolist() == [False, False]


def test_swap_conflict_keeps_both_robots_in_place_and_flags_both() -> None:
    core = make_core(OPEN_3X4, [(0, 0), (0, 1)], FAR[:2])
    out = step(core, R, L)
    assert positions(core) == [(0, 0), (0, 1)]
    assert out.collision[0].tolist() == [True, True]


def test_entering_the_cell_of_a_robot_that_stays_is_blocked() -> None:
    core = make_core(OPEN_3X4, [(0, 0), (0, 1)], FAR[:2])
    out = step(core, R, W)
    assert positions(core) == [(0, 0), (0, 1)]
    # Both are involved in the conflict (docs/decisions/0002).
    assert out.collision[0].tolist() == [True, True]


def test_following_a_robot_that_leaves_is_allowed() -> None:
    core = make_core(OPEN_3X4, [(0, 0), (0, 1)], FAR[:2])
    out = step(core, R, R)
    assert positions(core) == [(0, 1), (0, 2)]
    assert not out.collision.any()


def test_rotation_around_a_four_cycle_is_allowed() -> None:
    core = make_core("..\n..", [(0, 0), (0, 1), (1, 1), (1, 0)], [(1, 1), (1, 0), (0, 0), (0, 1)])
    out = step(core, R, D, L, U)  # clockwise
    assert positions(core) == [(0, 1), (1, 1), (1, 0), (0, 0)]
    assert not out.collision.any()


def test_a_blocked_head_cascades_down_a_chain_of_followers() -> None:
    # Corridor row 0; the head (0,3) and a robot from (1,4) both want (0,4).
    floor = ".....\n@@@@.\n....."
    starts = [(0, 0), (0, 1), (0, 2), (0, 3), (1, 4), (2, 0)]
    goals = [(2, 1), (2, 2), (2, 3), (2, 4), (0, 0), (0, 1)]
    core = make_core(floor, starts, goals)
    out = step(core, R, R, R, R, U, R)
    # Every follower ends up blocked by the one in front once the head is held back;
    # the bystander in the bottom row moves freely.
    assert positions(core) == [(0, 0), (0, 1), (0, 2), (0, 3), (1, 4), (2, 1)]
    assert out.collision[0].tolist() == [True, True, True, True, True, False]


def test_a_move_into_a_shelf_or_off_the_grid_is_invalid_not_a_collision() -> None:
    core = make_core(".@.\n...", [(0, 0), (1, 2)], [(1, 0), (0, 2)])
    out = step(core, R, D)  # into the shelf; off the bottom edge
    assert positions(core) == [(0, 0), (1, 2)]
    assert out.invalid[0].tolist() == [True, True]
    assert not out.collision.any()
    out = step(core, W, U)  # Wait is never invalid; a valid move is not either
    assert out.invalid[0].tolist() == [False, False]
    assert positions(core) == [(0, 0), (0, 2)]


def test_on_goal_remove_takes_the_robot_off_the_floor() -> None:
    core = make_core(OPEN_3X4, [(0, 0), (0, 2)], [(0, 1), (2, 3)], on_goal="remove")
    out = step(core, R, W)
    assert out.reached[0].tolist() == [True, False]
    assert core.done[0].tolist() == [True, False]
    assert core.occupying[0].tolist() == [False, True]
    out = step(core, D, L)  # robot 1 enters the finished robot's cell; robot 0 is frozen
    assert positions(core)[1] == (0, 1)
    assert not out.collision.any()
    assert out.active[0].tolist() == [False, True]
    assert out.reached[0].tolist() == [False, False]  # first arrival counts only once
    assert out.progress[0, 0] == out.goal_bonus[0, 0] == out.time_penalty[0, 0] == 0.0


def test_on_goal_stay_keeps_the_robot_as_an_obstacle_that_only_waits() -> None:
    core = make_core(OPEN_3X4, [(0, 0), (0, 2)], [(0, 1), (2, 3)], on_goal="stay")
    step(core, R, W)
    assert core.done[0].tolist() == [True, False]
    assert core.occupying[0].tolist() == [True, True]
    out = step(core, D, L)  # robot 0's Down is replaced by Wait; robot 1 bumps into it
    assert positions(core) == [(0, 1), (0, 2)]
    assert core.prev_actions[0].tolist() == [W, L]
    assert out.collision[0].tolist() == [False, True]  # a finished robot earns no terms
    assert out.collision_penalty[0, 0] == 0.0
    assert out.invalid[0, 0] == np.False_


def test_termination_and_truncation_are_kept_apart() -> None:
    core = make_core(OPEN_3X4, [(0, 0)], [(0, 1)], horizon=1)
    out = step(core, R)  # reaches its goal at the horizon: terminated, not truncated
    assert out.terminated.tolist() == [True]
    assert out.truncated.tolist() == [False]

    core = make_core(OPEN_3X4, [(0, 0)], [(0, 3)], horizon=2)
    out = step(core, R)
    assert out.terminated.tolist() == [False] and out.truncated.tolist() == [False]
    out = step(core, R)  # t = T, goal not reached
    assert out.terminated.tolist() == [False]
    assert out.truncated.tolist() == [True]
    out = step(core, R)  # an ended episode is frozen and reports neither again
    assert positions(core) == [(0, 2)]
    assert out.terminated.tolist() == [False] and out.truncated.tolist() == [False]
    assert out.reward.tolist() == [0.0]
    assert out.active.tolist() == [[False]]


def test_episodes_in_a_batch_end_independently() -> None:
    layout = from_ascii(OPEN_3X4)
    config = EnvConfig.make(n_robots=1, groups=1, horizon=5)
    core = WarehouseCore(config, layout=layout)
    starts = layout.to_index(np.array([[[0, 0]], [[1, 0]]]))
    goals = layout.to_index(np.array([[[0, 1]], [[1, 3]]]))
    core.reset(starts, goals)
    out = core.step(np.array([[R], [R]]))
    assert out.terminated.tolist() == [True, False]
    assert core.ended.tolist() == [True, False]
    core.step(np.array([[L], [R]]))  # episode 0 is frozen, episode 1 moves on
    assert core.pos[:, 0].tolist() == [int(goals[0, 0]), int(layout.to_index(np.array([1, 2])))]


def test_reward_terms_match_hand_computed_values_with_custom_weights() -> None:
    # q_p 1.5, q_g 7, q_c 3, q_tau 0.25. Robot 0 steps towards its goal, robot 1 reaches
    # its goal, robots 2 and 3 collide (vertex conflict), robot 4 steps away from its goal.
    floor = ".....\n.....\n....."
    starts = [(0, 0), (1, 0), (2, 0), (2, 2), (0, 4)]
    goals = [(0, 3), (1, 1), (1, 3), (0, 2), (2, 4)]
    core = make_core(floor, starts, goals, q_p=1.5, q_g=7.0, q_c=3.0, q_tau=0.25)
    out = step(core, R, R, R, L, U)
    assert positions(core) == [(0, 1), (1, 1), (2, 0), (2, 2), (0, 4)]
    assert out.progress[0].tolist() == [1.5, 1.5, 0.0, 0.0, 0.0]  # robot 4: Up is off-grid
    assert out.invalid[0].tolist() == [False, False, False, False, True]
    assert out.goal_bonus[0].tolist() == [0.0, 7.0, 0.0, 0.0, 0.0]
    assert out.collision_penalty[0].tolist() == [0.0, 0.0, -3.0, -3.0, 0.0]
    assert out.time_penalty[0].tolist() == [-0.25, 0.0, -0.25, -0.25, -0.25]
    team = (1.5 - 0.25) + (1.5 + 7.0) + (-3.0 - 0.25) * 2 + (-0.25)
    assert out.reward[0] == pytest.approx(team / 5)
    out = step(core, W, W, W, W, L)  # moving away costs progress
    assert out.progress[0].tolist() == [0.0, 0.0, 0.0, 0.0, -1.5]
    assert out.time_penalty[0, 1] == 0.0  # finished robots pay no time penalty


def test_actions_outside_zero_to_four_are_rejected() -> None:
    core = make_core(OPEN_3X4, [(0, 0), (0, 2)], FAR[:2])
    with pytest.raises(BenchError, match=r"action 5 outside 0\.\.4"):
        step(core, R, 5)
    with pytest.raises(BenchError, match=r"action -1 outside 0\.\.4"):
        step(core, -1, R)


def test_actions_of_the_wrong_shape_are_rejected() -> None:
    core = make_core(OPEN_3X4, [(0, 0), (0, 2)], FAR[:2])
    with pytest.raises(BenchError, match=r"actions must be shaped \(1, 2\), got \(1, 3\)"):
        step(core, R, R, R)
    with pytest.raises(BenchError, match=r"got \(2,\)"):
        core.step(np.array([R, R]))


def test_reset_with_mismatched_shapes_is_rejected() -> None:
    core = make_core(OPEN_3X4, [(0, 0), (0, 2)], FAR[:2])
    with pytest.raises(BenchError, match=r"must both be \(B, 2\)"):
        core.reset(np.zeros((1, 3), np.int64), np.ones((1, 3), np.int64))


def test_reset_refuses_two_robots_on_one_cell_and_cells_off_the_layout() -> None:
    """Two robots on one cell would never leave the conflict resolution (a hang), so reset
    refuses them, naming the episode and the cell; a robot that starts on its own goal is
    off the floor under "remove" and may share its cell."""
    core = make_core(OPEN_3X4, [(0, 0), (0, 2)], FAR[:2])
    starts, goals = core.pos.copy(), core.goal.copy()
    dup = np.concatenate([starts, starts], axis=0)
    dup[1, 1] = dup[1, 0]
    with pytest.raises(BenchError, match=rf"episode 1 has two robots starting on free cell {int(dup[1, 0])}"):
        core.reset(dup, np.concatenate([goals, goals], axis=0))
    core.reset(np.array([[goals[0, 0], goals[0, 0]]]), goals)  # robot 0 starts on its goal: off the floor
    assert core.occupying.tolist() == [[False, True]]
    stay = make_core(OPEN_3X4, [(0, 0), (0, 2)], FAR[:2], on_goal="stay")
    with pytest.raises(BenchError, match="two robots starting on free cell"):
        stay.reset(np.array([[goals[0, 0], goals[0, 0]]]), goals)  # "stay": it occupies its goal
    f = core.layout.n_free
    with pytest.raises(BenchError, match=rf"starts must be free-cell indices in 0\.\.{f - 1}, got 0\.\.{f}"):
        core.reset(np.array([[0, f]]), goals)
    with pytest.raises(BenchError, match=r"goals must be free-cell indices"):
        core.reset(starts, np.array([[-1, 3]]))


def test_too_many_robots_for_the_layout_is_a_clear_error() -> None:
    layout = from_ascii("..@\n.@@", name="closet")
    with pytest.raises(BenchError, match="'closet' has 3 connected free cells, too few for 4 robots"):
        sample_scenarios(layout, 4, 1, np.random.default_rng(0))


def test_unreachable_goal_in_an_explicit_scenario_is_rejected() -> None:
    layout = from_ascii("..@..", name="split")
    with pytest.raises(BenchError, match=r"goal \(0, 3\) of robot 1 is unreachable from its start \(0, 1\)"):
        validate_scenario(layout, 2, [(0, 0), (0, 1)], [(0, 1), (0, 3)])


def test_start_list_of_the_wrong_length_is_rejected() -> None:
    layout = from_ascii(OPEN_3X4)
    with pytest.raises(BenchError, match="starts: 2 cells given for n_robots=3"):
        validate_scenario(layout, 3, [(0, 0), (0, 1)], FAR[:3])


def test_shared_or_blocked_start_cells_are_rejected() -> None:
    layout = from_ascii("...\n.@.")
    with pytest.raises(BenchError, match="starts: cells must be distinct"):
        validate_scenario(layout, 2, [(0, 0), (0, 0)], [(0, 1), (0, 2)])
    with pytest.raises(BenchError, match=r"goals cell \(1, 1\) is an obstacle"):
        validate_scenario(layout, 2, [(0, 0), (0, 1)], [(1, 1), (0, 2)])


def test_sample_scenarios__single_robot_never_starts_on_its_goal():
    import numpy as np

    from envs.layouts import from_ascii
    from envs.scenarios import sample_scenarios

    two_cells = from_ascii("..", name="two")
    for seed in range(20):
        s, g = sample_scenarios(two_cells, 1, 3, np.random.default_rng(seed))
        assert (s != g).all()
