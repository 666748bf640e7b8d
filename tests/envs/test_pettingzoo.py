"""The PettingZoo adapter: API contract, seeding, equivalence with the core, rendering."""
from __future__ import annotations

import io
import pickle

import imageio.v3 as iio
import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, render_test
from pettingzoo.utils.conversions import parallel_to_aec

from envs.config import EnvConfig
from envs.core import WarehouseCore
from envs.errors import BenchError
from envs.layouts import from_ascii, load_layout
from envs.observations import robot_features
from envs.render import render_ansi, render_rgb, show_in_terminal, write_gif
from envs.scenarios import sample_scenarios
from envs.warehouse_v0 import parallel_env

SMALL = dict(n_robots=6, groups=3, layout="tiny", horizon=40)


def random_actions(env, obs, rng):
    """A masked random action for every live agent."""
    acts = {}
    for a in env.agents:
        allowed = np.flatnonzero(obs[a]["action_mask"])
        acts[a] = int(rng.choice(allowed))
    return acts


# --------------------------------------------------------------- PettingZoo checkers
@pytest.mark.parametrize("on_goal", ["remove", "stay"])
def test_warehouse_v0__passes_parallel_api_test(on_goal):
    parallel_api_test(parallel_env(**SMALL, on_goal=on_goal), num_cycles=60)


def test_warehouse_v0__passes_parallel_api_test_when_all_robots_finish():
    # Two robots on a 2x2 floor: episodes end by termination, not at the horizon.
    layout = from_ascii("@@@@\n@..@\n@..@\n@@@@", "square")
    env = parallel_env(n_robots=2, groups=2, layout=layout, horizon=400)
    for i, a in enumerate(env.possible_agents):
        env.action_space(a).seed(i)
    parallel_api_test(env, num_cycles=400)
    assert env.core.ended[0] and env.core.done.all() and env.core.t < 400


def test_warehouse_v0__passes_parallel_seed_test():
    parallel_seed_test(lambda: parallel_env(**SMALL), num_cycles=60)


def test_warehouse_v0__passes_aec_api_test():
    api_test(parallel_to_aec(parallel_env(**SMALL)), num_cycles=30)


@pytest.mark.parametrize("flat_obs", [False, True])
def test_warehouse_v0__passes_checkers_with_flat_observations(flat_obs):
    parallel_api_test(parallel_env(**SMALL, flat_obs=flat_obs), num_cycles=40)
    api_test(parallel_to_aec(parallel_env(**SMALL, flat_obs=flat_obs)), num_cycles=20)


def test_warehouse_v0__passes_render_test_unmodified(capsys):
    render_test(lambda render_mode=None: parallel_to_aec(
        parallel_env(**SMALL, render_mode=render_mode)))
    printed = capsys.readouterr().out  # "human": text frames on stdout, render() -> None
    assert printed.count("t=") >= 5 and "@" in printed


def test_warehouse_v0__human_mode_prints_the_ansi_frame(capsys):
    env = parallel_env(**SMALL, render_mode="human")
    env.reset(seed=1)
    assert env.render() is None
    text = parallel_env(**SMALL, render_mode="ansi")
    text.reset(seed=1)
    assert capsys.readouterr().out == text.render() + "\n\n"  # not a TTY: no clear codes


def test_show_in_terminal__clears_the_screen_on_a_tty():
    class Tty(io.StringIO):
        def isatty(self):
            return True
    out = Tty()
    show_in_terminal("frame", out)
    assert out.getvalue() == "\x1b[H\x1b[2Jframe\n"


def test_warehouse_v0__unknown_render_mode_is_an_error():
    with pytest.raises(BenchError, match="render_mode 'video'"):
        parallel_env(**SMALL, render_mode="video")


def test_warehouse_v0__bad_config_names_the_field():
    with pytest.raises(BenchError, match="loss_p"):
        parallel_env(**SMALL, loss_p=1.5)


def test_warehouse_v0__spaces_are_cached_and_observations_fit():
    env = parallel_env(**SMALL)
    obs, _ = env.reset(seed=0)
    for a in env.possible_agents:
        assert env.observation_space(a) is env.observation_space(a)
        assert env.action_space(a) is env.action_space(a)
        assert env.observation_space(a).contains(obs[a])
    assert env.state().shape == env.state_space.shape
    assert env.state_space.contains(env.state())


def test_warehouse_v0__pickle_round_trip_continues_identically():
    env = parallel_env(**SMALL, loss_p=0.5)
    obs, _ = env.reset(seed=5)
    rng = np.random.default_rng(0)
    for _ in range(3):
        obs, *_ = env.step(random_actions(env, obs, rng))
    clone = pickle.loads(pickle.dumps(env))
    for _ in range(10):
        if not env.agents:
            break
        acts = random_actions(env, obs, rng)
        obs, rew, term, trunc, info = env.step(acts)
        obs2, rew2, term2, trunc2, info2 = clone.step(acts)
        assert rew == rew2 and term == term2 and trunc == trunc2
        for a in obs:
            np.testing.assert_array_equal(obs[a]["observation"], obs2[a]["observation"])
            np.testing.assert_array_equal(info[a]["link_available"], info2[a]["link_available"])
            assert info[a]["position"] == info2[a]["position"]


# ------------------------------------------------------------ equivalence with core
@pytest.mark.parametrize("on_goal", ["remove", "stay"])
def test_warehouse_v0__matches_batched_core_with_b1(on_goal):
    cfg = dict(n_robots=10, groups=2, layout="tiny", horizon=60, on_goal=on_goal)
    env = parallel_env(**cfg)
    obs, infos = env.reset(seed=11)
    # The adapter samples its scenario exactly like sample_scenarios with the seed's rng.
    layout = load_layout("tiny")
    starts, goals = sample_scenarios(layout, 10, 1, np.random.default_rng(11))
    core = WarehouseCore(EnvConfig(**cfg), layout)
    core.reset(starts, goals)
    for i, a in enumerate(env.possible_agents):
        assert infos[a]["position"] == tuple(layout.cells[starts[0, i]])
        assert infos[a]["goal"] == tuple(layout.cells[goals[0, i]])

    rng = np.random.default_rng(3)
    steps = 0
    while env.agents:
        acts = random_actions(env, obs, rng)
        u = np.full((1, 10), 4)
        for a, act in acts.items():
            u[0, int(a.split("_")[1])] = act
        live = list(env.agents)
        obs, rew, term, trunc, infos = env.step(acts)
        res = core.step(u)
        steps += 1
        assert set(rew) == set(live)
        for a in live:
            i = int(a.split("_")[1])
            assert rew[a] == float(res.reward[0])
            assert infos[a]["position"] == tuple(layout.cells[core.pos[0, i]])
            assert infos[a]["collision"] == bool(res.collision[0, i])
            assert infos[a]["progress"] == res.progress[0, i]
            assert infos[a]["goal_bonus"] == res.goal_bonus[0, i]
            assert infos[a]["collision_penalty"] == res.collision_penalty[0, i]
            assert infos[a]["time_penalty"] == res.time_penalty[0, i]
            assert infos[a]["invalid"] == bool(res.invalid[0, i])
        if res.terminated[0] or res.truncated[0]:
            assert env.agents == []
    assert steps == core.t
    assert core.ended[0]


def test_warehouse_v0__remove_mode_terminates_robot_on_arrival():
    layout = from_ascii("@@@@@\n@...@\n@...@\n@@@@@", "box")
    env = parallel_env(n_robots=2, groups=1, layout=layout, horizon=10)
    env.reset(options={"starts": [(1, 1), (2, 3)], "goals": [(1, 2), (2, 1)]})
    obs, rew, term, trunc, infos = env.step({"robot_0": 3, "robot_1": 2})  # 0 arrives
    assert term == {"robot_0": True, "robot_1": False}
    assert trunc == {"robot_0": False, "robot_1": False}
    assert rew["robot_0"] == rew["robot_1"]  # shared team reward
    assert infos["robot_0"]["at_goal"] and infos["robot_0"]["goal_bonus"] > 0
    assert env.agents == ["robot_1"]
    _, _, term, _, _ = env.step({"robot_1": 2})
    assert term == {"robot_1": True} and env.agents == []


def test_warehouse_v0__horizon_truncates_every_remaining_agent():
    env = parallel_env(n_robots=3, groups=1, layout="tiny", horizon=2)
    env.reset(seed=0)
    for _ in range(2):
        _, _, term, trunc, _ = env.step(dict.fromkeys(env.agents, 4))
    assert all(trunc.values()) and not any(term.values()) and len(trunc) == 3
    assert env.agents == []


@pytest.mark.parametrize(("on_goal", "robot_0_terminated"), [("remove", True), ("stay", False)])
def test_warehouse_v0__a_robot_arriving_at_the_horizon(on_goal: str, robot_0_terminated: bool):
    # "remove": the arriving robot is terminated, the other truncated; "stay": nobody is
    # terminated alone, so both are truncated (docs/decisions/0016).
    env = parallel_env(layout="tiny", n_robots=2, groups=1, horizon=1, on_goal=on_goal)
    env.reset(seed=0, options={"starts": [(1, 1), (7, 9)], "goals": [(1, 2), (1, 5)]})
    _, _, term, trunc, infos = env.step({"robot_0": 3, "robot_1": 4})
    assert infos["robot_0"]["at_goal"] and not infos["robot_1"]["at_goal"]
    assert term == {"robot_0": robot_0_terminated, "robot_1": False}
    assert trunc == {"robot_0": not robot_0_terminated, "robot_1": True}
    assert env.agents == []


def test_warehouse_v0__stay_mode_keeps_finished_robot_with_wait_only():
    layout = from_ascii("@@@@@\n@...@\n@...@\n@@@@@", "box")
    env = parallel_env(n_robots=2, groups=1, layout=layout, horizon=10, on_goal="stay")
    env.reset(options={"starts": [(1, 1), (2, 3)], "goals": [(1, 2), (2, 1)]})
    obs, _, term, _, _ = env.step({"robot_0": 3, "robot_1": 4})
    assert not any(term.values()) and env.agents == ["robot_0", "robot_1"]
    np.testing.assert_array_equal(obs["robot_0"]["action_mask"], [0, 0, 0, 0, 1])


# ------------------------------------------------------------------ explicit scenarios
def test_warehouse_v0__explicit_scenario_places_robots_where_asked():
    env = parallel_env(**SMALL)
    starts = [(1, 1), (1, 2), (4, 1), (4, 5), (7, 11), (1, 11)]
    goals = [(7, 1), (7, 2), (4, 11), (1, 6), (1, 1), (7, 6)]
    _, infos = env.reset(seed=0, options={"starts": starts, "goals": goals})
    assert [infos[a]["position"] for a in env.possible_agents] == starts
    assert [infos[a]["goal"] for a in env.possible_agents] == goals
    assert [infos[a]["group"] for a in env.possible_agents] == [0, 1, 2, 0, 1, 2]


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"starts": [(1, 1)] * 2, "goals": [(7, 1)] * 6}, "2 cells given for n_robots=6"),
        ({"starts": [(0, 0), (1, 2), (4, 1), (4, 5), (7, 11), (1, 11)]}, "both 'starts' and 'goals'"),
        ({"starts": [(0, 0), (1, 2), (4, 1), (4, 5), (7, 11), (1, 11)],
          "goals": [(7, 1), (7, 2), (4, 11), (1, 6), (1, 1), (7, 6)]}, r"\(0, 0\) is an obstacle"),
        ({"starts": [(1, 1), (1, 1), (4, 1), (4, 5), (7, 11), (1, 11)],
          "goals": [(7, 1), (7, 2), (4, 11), (1, 6), (1, 1), (7, 6)]}, "distinct"),
        ({"starts": [(1, 1), (1, 2), (4, 1), (4, 5), (7, 11), (1, 11)],
          "goals": [(7, 1), (7, 2), (4, 11), (1, 6), (1, 1), (70, 6)]}, "outside"),
    ],
)
def test_warehouse_v0__bad_scenario_options_raise_bench_error(options, message):
    env = parallel_env(**SMALL)
    with pytest.raises(BenchError, match=message):
        env.reset(seed=0, options=options)


def test_warehouse_v0__unreachable_goal_raises_bench_error():
    layout = from_ascii("@@@@@@@\n@..@..@\n@@@@@@@", "split")
    env = parallel_env(n_robots=1, groups=1, layout=layout)
    with pytest.raises(BenchError, match=r"goal \(1, 4\) of robot 0 is unreachable"):
        env.reset(options={"starts": [(1, 1)], "goals": [(1, 4)]})


# ----------------------------------------------------------------------- action mask
def test_warehouse_v0__action_mask_blocks_walls_and_keeps_wait():
    layout = from_ascii("@@@@\n@..@\n@.@@\n@@@@", "corner")
    env = parallel_env(n_robots=1, groups=1, layout=layout)
    obs, infos = env.reset(options={"starts": [(1, 1)], "goals": [(2, 1)]})
    # From (1, 1): Up wall, Down free, Left wall, Right free, Wait.
    np.testing.assert_array_equal(obs["robot_0"]["action_mask"], [0, 1, 0, 1, 1])
    assert obs["robot_0"]["action_mask"].dtype == np.int8
    assert all("action_mask" not in info for info in infos.values())  # SPEC 2: obs only
    # A masked move still steps: the robot stays in place and the move counts as invalid.
    _, _, _, _, infos = env.step({"robot_0": 0})
    assert infos["robot_0"]["position"] == (1, 1) and infos["robot_0"]["invalid"]


def test_warehouse_v0__step_without_action_for_live_agent_is_an_error():
    env = parallel_env(**SMALL)
    env.reset(seed=0)
    with pytest.raises(BenchError, match="no action for live agents"):
        env.step({"robot_0": 4})


# ------------------------------------------------------------------ channel in infos
def test_warehouse_v0__infos_carry_group_links_and_payload():
    env = parallel_env(n_robots=8, groups=4, layout="tiny", loss_p=0.5)
    obs, infos = env.reset(seed=2)
    seen = []
    for _ in range(20):
        obs, _, _, _, infos = env.step(dict.fromkeys(env.agents, 4))
        info = infos["robot_1"]  # group 1
        links = info["link_available"]
        assert links.shape == (4,) and not links[1]  # no inter-group link to itself
        np.testing.assert_array_equal(links, env.links[:, 1])
        assert info["payload_hier"] == 8 * 3 * 3 and info["payload_dec"] == 8 * 7 * 3
        seen.append(links[[0, 2, 3]])
    frac = np.mean(seen)
    assert 0.2 < frac < 0.8  # p = 0.5: some links lost, some delivered


# --------------------------------------------------------------------------- render
def test_render_rgb__colours_cells_robots_and_markers():
    obstacles = np.array([[0, 1, 0], [0, 0, 0]], dtype=bool)
    pos = np.array([[0, 0], [1, 2]])
    goals = np.array([[1, 0], [0, 2]])
    frame = render_rgb(obstacles, pos, goals, np.array([0, 1]), collision=np.array([False, True]),
                       cell_px=8)
    assert frame.shape == (16, 24, 3) and frame.dtype == np.uint8
    np.testing.assert_array_equal(frame[4, 12], [64, 64, 64])  # shelf
    np.testing.assert_array_equal(frame[4, 4], [31, 119, 180])  # robot 0, group 0
    np.testing.assert_array_equal(frame[8 + 4, 16 + 4], [255, 127, 14])  # robot 1 body
    np.testing.assert_array_equal(frame[8, 16], [220, 20, 20])  # robot 1 collision border
    np.testing.assert_array_equal(frame[8 + 2, 2], [31, 119, 180])  # goal 0 outline
    np.testing.assert_array_equal(frame[8 + 4, 4], [255, 255, 255])  # goal 0 inside
    with_links = render_rgb(obstacles, pos, goals, np.array([0, 1]), cell_px=8,
                            links=np.array([[False, False], [True, False]]))
    assert with_links.shape[0] > 16 and with_links.shape[1:] == (24, 3)
    plain = render_rgb(obstacles, pos, goals, np.array([0, 1]), cell_px=8)
    np.testing.assert_array_equal(with_links[-16:], plain)  # the strip sits on top


def test_render_ansi__letters_for_groups_and_goals():
    text = render_ansi(np.array([[0, 1, 0]], dtype=bool), np.array([[0, 0]]),
                       np.array([[0, 2]]), np.array([1]), header="t=0")
    assert text == "t=0\nB@b"


def test_warehouse_v0__writes_readable_gif_with_one_frame_per_step(tmp_path):
    # One group: no link strip, so waiting robots give identical consecutive scenes.
    env = parallel_env(n_robots=6, groups=1, layout="tiny", record=True, render_mode="rgb_array")
    env.reset(seed=4)
    for _ in range(7):  # all Wait: identical consecutive scenes must still be 8 frames
        env.step(dict.fromkeys(env.agents, 4))
    path = env.write_episode_gif(str(tmp_path / "ep.gif"))
    frames = iio.imread(path, index=None)
    assert frames.shape[0] == 8
    assert frames.shape[1:3] == env.render().shape[:2]
    assert not list(tmp_path.glob(".*tmp"))  # no temp file left behind


def test_write_gif__rejects_empty_frames(tmp_path):
    with pytest.raises(BenchError, match="no frames"):
        write_gif([], tmp_path / "x.gif")


# --------------------------------------------------- wrappers need
def test_warehouse_v0__robot_starting_on_its_goal_is_in_reset_and_ends_at_first_step():
    layout = from_ascii("@@@@@\n@...@\n@...@\n@@@@@", "box")
    env = parallel_env(n_robots=2, layout=layout, horizon=10)
    obs, infos = env.reset(options={"starts": [(1, 1), (2, 3)], "goals": [(1, 1), (2, 1)]})
    assert env.agents == ["robot_0", "robot_1"] and set(obs) == set(infos) == set(env.agents)
    np.testing.assert_array_equal(obs["robot_0"]["action_mask"], [0, 0, 0, 0, 1])
    assert infos["robot_0"]["at_goal"]
    _, rew, term, trunc, _ = env.step({"robot_0": 4, "robot_1": 2})
    assert term == {"robot_0": True, "robot_1": False} and not any(trunc.values())
    assert rew["robot_0"] == rew["robot_1"] and env.agents == ["robot_1"]


def test_warehouse_v0__sampled_scenarios_never_start_a_robot_on_its_goal():
    env = parallel_env(n_robots=30, layout="tiny")
    for seed in range(30):
        _, infos = env.reset(seed=seed)
        assert not any(info["at_goal"] for info in infos.values())


def test_warehouse_v0__groups_default_to_min_4_n():
    assert parallel_env(n_robots=2, layout="tiny").config.groups == 2
    assert parallel_env(n_robots=3, layout="tiny").config.groups == 3
    assert parallel_env(n_robots=9, layout="tiny").config.groups == 4
    assert parallel_env(n_robots=2, groups=1, layout="tiny").config.groups == 1
    assert EnvConfig.make(n_robots=2).groups == 2
    with pytest.raises(BenchError, match="groups=4 exceeds n_robots=2"):
        parallel_env(n_robots=2, groups=4, layout="tiny")


def test_warehouse_v0__flat_observation_is_features_then_mask():
    env = parallel_env(**SMALL, flat_obs=True)
    ref = parallel_env(**SMALL)
    obs, _ = env.reset(seed=3)
    obs_ref, _ = ref.reset(seed=3)
    for a in env.agents:
        assert obs[a].dtype == np.float32 and env.observation_space(a).contains(obs[a])
        np.testing.assert_array_equal(obs[a], np.concatenate(
            [obs_ref[a]["observation"], obs_ref[a]["action_mask"].astype(np.float32)]))


def test_warehouse_v0__observations_are_views_of_one_batched_array():
    env = parallel_env(**SMALL)
    obs, _ = env.reset(seed=0)
    base = obs["robot_0"]["observation"].base
    assert base is not None and all(obs[a]["observation"].base is base for a in env.agents)
    feats = robot_features(env.core, env.patch, env.groups)[0]
    np.testing.assert_array_equal(np.stack([obs[a]["observation"] for a in env.agents]), feats)
    _, infos = env.reset(seed=0)
    infos["robot_0"]["terminal_observation"] = 1  # SuperSuit writes into infos
