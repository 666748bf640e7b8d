"""The PettingZoo adapter's input checks: actions, reset options, calls out of order.

Every mistake is one ``BenchError`` (a ``ValueError``) naming the agent or option and the
value; nothing steps.
"""
from __future__ import annotations

import numpy as np
import pytest

from envs.errors import BenchError
from envs.layouts import from_ascii
from envs.warehouse_v0 import parallel_env

SMALL = dict(n_robots=6, groups=3, layout="tiny", horizon=40)


def test_warehouse_v0__step_or_state_before_reset_is_an_error():
    env = parallel_env(**SMALL)
    with pytest.raises(BenchError, match=r"call reset\(\) before step"):
        env.step({"robot_77": "garbage"})
    with pytest.raises(BenchError, match=r"call reset\(\) before state"):
        env.state()


def test_warehouse_v0__step_after_the_episode_ended_is_an_error():
    env = parallel_env(n_robots=3, layout="tiny", horizon=1)
    env.reset(seed=0)
    env.step(dict.fromkeys(env.agents, 4))
    assert env.agents == []
    with pytest.raises(BenchError, match=r"episode ended at t=1.*call reset\(\)"):
        env.step({})
    env.reset(seed=0)  # and a reset starts over
    env.step(dict.fromkeys(env.agents, 4))


@pytest.mark.parametrize("bad", [1.5, 1.0, "1", True, np.bool_(True), None, "up", float("nan"),
                                 -1, 5, np.int64(7), np.array([1]), np.float32(2.0)])
def test_warehouse_v0__non_integer_or_out_of_range_action_names_agent_and_value(bad):
    env = parallel_env(**SMALL)
    env.reset(seed=0)
    acts = dict.fromkeys(env.agents, 4)
    acts["robot_3"] = bad
    with pytest.raises(BenchError, match=r"action .* for live agent 'robot_3' is not an integer in 0\.\.4"):
        env.step(acts)
    assert env.core.t == 0  # nothing moved


@pytest.mark.parametrize("good", [3, np.int64(3), np.int32(3), np.uint8(3), np.array(3)])
def test_warehouse_v0__integer_actions_of_any_numpy_kind_are_accepted(good):
    env = parallel_env(**SMALL)
    env.reset(seed=0)
    acts = dict.fromkeys(env.agents, 4)
    acts["robot_3"] = good
    env.step(acts)
    assert env.core.prev_actions[0, 3] == 3


def test_warehouse_v0__unknown_agent_in_actions_is_an_error():
    env = parallel_env(**SMALL)
    env.reset(seed=0)
    with pytest.raises(BenchError, match="unknown agent 'robot_77'"):
        env.step({**dict.fromkeys(env.agents, 4), "robot_77": 4})
    with pytest.raises(BenchError, match="actions must be a dict"):
        env.step([4] * 6)


def _arrive_first_step(on_goal):
    layout = from_ascii("@@@@@\n@...@\n@...@\n@@@@@", "box")
    env = parallel_env(n_robots=2, layout=layout, horizon=10, on_goal=on_goal)
    env.reset(options={"starts": [(1, 1), (2, 3)], "goals": [(1, 2), (2, 1)]})
    env.step({"robot_0": 3, "robot_1": 2})  # robot_0 arrives
    return env


def test_warehouse_v0__finished_agent_may_be_absent_none_or_any_valid_action():
    env = _arrive_first_step("remove")
    assert env.agents == ["robot_1"]
    for finished in ({}, {"robot_0": None}, {"robot_0": 4}, {"robot_0": 1}):
        before = env.core.t
        env.step({"robot_1": 4, **finished})
        assert env.core.t == before + 1 and env.agents == ["robot_1"]
    with pytest.raises(BenchError, match="action 'x' for finished agent 'robot_0'"):
        env.step({"robot_1": 4, "robot_0": "x"})
    with pytest.raises(BenchError, match="action None for live agent 'robot_1'"):
        env.step({"robot_1": None})


def test_warehouse_v0__stay_mode_finished_robot_waits_whatever_its_action():
    env = _arrive_first_step("stay")
    pos = env.core.pos.copy()
    _, _, _, _, infos = env.step({"robot_0": 2, "robot_1": 4})  # a move: masked, ignored
    np.testing.assert_array_equal(env.core.pos, pos)
    assert not infos["robot_0"]["invalid"] and infos["robot_0"]["position"] == (1, 2)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"start": [(1, 1)], "goals": [(1, 2)]}, "unknown option 'start'; did you mean 'starts'"),
        ({"starts": [(1, 1)], "Goals": [(1, 2)]}, "unknown option 'Goals'; did you mean 'goals'"),
        ([(1, 1)], "options must be a dict"),
        ("starts", "options must be a dict"),
        ({"starts": [(1.0, 1)], "goals": [(1, 2)]}, "starts must hold integer .* float64"),
        ({"starts": [(1, 1)], "goals": [(1.5, 2)]}, "goals must hold integer"),
        ({"starts": [(True, 1)], "goals": [(1, 2)]}, "starts must hold integer .* bool values such as True"),
        ({"starts": [(1, 1)], "goals": [("1", 2)]}, "goals must hold integer"),
        ({"starts": [(1, 1), (1,)], "goals": [(1, 2)]}, "starts must be a list of"),
    ],
)
def test_warehouse_v0__bad_reset_options_are_errors(options, message):
    env = parallel_env(n_robots=1, layout="tiny")
    with pytest.raises(BenchError, match=message):
        env.reset(options=options)


def test_warehouse_v0__other_reset_options_are_ignored_with_a_warning():
    env = parallel_env(**SMALL)
    with pytest.warns(UserWarning, match="option 'speed' is not used"):
        obs, _ = env.reset(seed=0, options={"speed": 2})
    obs2, _ = parallel_env(**SMALL).reset(seed=0)
    np.testing.assert_array_equal(obs["robot_0"]["observation"], obs2["robot_0"]["observation"])


def test_bench_error_is_a_value_error():
    assert issubclass(BenchError, ValueError)


@pytest.mark.parametrize("huge", [2**70, np.uint64(2**64 - 1), -(2**70)])
def test_warehouse_v0__huge_integer_actions_are_errors_not_overflows(huge):
    env = parallel_env(**SMALL)
    env.reset(seed=0)
    with pytest.raises(BenchError, match="for live agent 'robot_0' is not an integer in 0..4"):
        env.step({**dict.fromkeys(env.agents, 4), "robot_0": huge})


def test_warehouse_v0__actions_in_any_order_or_subset_map_to_the_right_robots():
    env = _arrive_first_step("remove")  # robot_0 finished, robot_1 live
    env.step({"robot_1": 0, "robot_0": 3})  # reversed order, finished agent's action ignored
    assert env.core.prev_actions[0].tolist() == [4, 0]
