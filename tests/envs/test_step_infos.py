"""StepInfos: lazily built per-agent infos that behave as a plain dict on every read path."""
from __future__ import annotations

import copy
import json
import pickle

import numpy as np
import pytest

from envs.step_infos import INFO_KEYS, StepInfos
from envs.warehouse_v0 import parallel_env


def make_infos() -> tuple[StepInfos, dict]:
    """Two robots, agents robot_0 and robot_1 (indices 0 and 1), and the expected dicts."""
    columns = {
        "position": np.array([[1, 2], [3, 4]]), "goal": np.array([[5, 6], [7, 8]]),
        "group": np.array([0, 1]), "collision": np.array([True, False]),
        "at_goal": np.array([False, True]), "invalid": np.array([False, False]),
        "progress": np.array([1.0, -1.0]), "goal_bonus": np.array([0.0, 10.0]),
        "collision_penalty": np.array([-2.0, 0.0]), "time_penalty": np.array([-0.1, 0.0]),
        "link_available": np.array([[False, True], [True, False]]),
        "message_age": np.array([[0, 2], [0, 0]]),
    }
    consts = {"payload_hier": 12, "payload_dec": 6, "t": 3}
    infos = StepInfos(["robot_0", "robot_1"], {"robot_0": 0, "robot_1": 1}, columns, consts)
    want = {
        "robot_0": {"position": (1, 2), "goal": (5, 6), "group": 0, "collision": True,
                    "at_goal": False, "invalid": False, "progress": 1.0, "goal_bonus": 0.0,
                    "collision_penalty": -2.0, "time_penalty": -0.1, "payload_hier": 12,
                    "payload_dec": 6, "t": 3},
        "robot_1": {"position": (3, 4), "goal": (7, 8), "group": 1, "collision": False,
                    "at_goal": True, "invalid": False, "progress": -1.0, "goal_bonus": 10.0,
                    "collision_penalty": 0.0, "time_penalty": 0.0, "payload_hier": 12,
                    "payload_dec": 6, "t": 3},
    }
    return infos, want


def plain(d: dict) -> dict:
    """Drop the array entries so dicts compare with ==."""
    return {a: {k: v for k, v in info.items() if k not in ("link_available", "message_age")}
            for a, info in d.items()}


@pytest.mark.parametrize("read", [
    lambda x: {a: x[a] for a in x}, lambda x: dict(x), lambda x: {**x}, lambda x: x.copy(),
    lambda x: dict(x.items()), lambda x: dict(zip(x.keys(), x.values(), strict=True)),
    lambda x: {a: x.get(a) for a in ("robot_0", "robot_1")}, lambda x: pickle.loads(pickle.dumps(x)),
    lambda x: copy.copy(x), lambda x: copy.deepcopy(x), lambda x: x | {},
    lambda x: {} | x,
])
def test_step_infos__every_read_path_gives_the_built_dicts(read):
    infos, want = make_infos()
    got = read(infos)
    assert type(got["robot_0"]) is dict and plain(got) == want
    assert list(got["robot_0"]) == list(INFO_KEYS)
    np.testing.assert_array_equal(got["robot_1"]["link_available"], [True, False])
    np.testing.assert_array_equal(got["robot_0"]["message_age"], [0, 2])
    assert all(type(v) in (int, float, bool, tuple) for v in want["robot_0"].values())


def test_step_infos__copies_and_pickles_are_plain_dicts_without_the_columns():
    infos, _ = make_infos()
    for clone in (pickle.loads(pickle.dumps(infos)), copy.deepcopy(infos), copy.copy(infos)):
        assert type(clone) is dict


def test_step_infos__is_a_mutable_dict_like_supersuit_expects():
    infos, want = make_infos()
    assert isinstance(infos, dict) and len(infos) == 2 and "robot_1" in infos
    assert "robot_9" not in infos and infos.get("robot_9", {}) == {}
    infos["robot_0"]["terminal_observation"] = 7
    assert infos["robot_0"]["terminal_observation"] == 7  # kept: the same dict object
    assert infos.pop("robot_1")["at_goal"] is True and list(infos) == ["robot_0"]
    assert json.loads(json.dumps(plain(infos)))["robot_0"]["position"] == [1, 2]
    assert "'goal': (5, 6)" in repr(infos)


def test_step_infos__equal_to_a_dict_with_the_same_content():
    infos, want = make_infos()
    other, _ = make_infos()
    for a in want:
        for key in ("link_available", "message_age"):
            other[a].pop(key)
            infos[a].pop(key)
    assert infos == want and infos == other and not infos != want


def test_warehouse_v0__infos_match_eager_core_values_after_steps():
    env = parallel_env(n_robots=6, layout="tiny", horizon=20, loss_p=0.5)
    obs, infos = env.reset(seed=1)
    rng = np.random.default_rng(0)
    for _ in range(5):
        acts = {a: int(rng.integers(5)) for a in env.agents}
        obs, _, _, _, infos = env.step(acts)
        pos_then, links_then, t_then = env.core.pos.copy(), env.links.copy(), env.core.t
        res_then = env._last
        progress_then, collision_then = res_then.progress.copy(), res_then.collision.copy()
    res_then.progress += 1.0  # a core reusing its arrays in place must not change infos
    res_then.collision[:] = ~collision_then
    env.step(dict.fromkeys(env.agents, 4))  # later steps must not change earlier infos
    for a, info in infos.items():
        i = env.agent_ids[a]
        assert info["position"] == tuple(env.layout.cells[pos_then[0, i]])
        np.testing.assert_array_equal(info["link_available"], links_then[:, env.groups[i]])
        assert info["t"] == t_then == 5
        assert info["progress"] == progress_then[0, i]
        assert info["collision"] == collision_then[0, i]
