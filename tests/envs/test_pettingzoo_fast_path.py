"""The PettingZoo adapter's step (templates for the flag dicts, masks from one table, core
``step_checked``, the fast ``robot_features``) against its plain form
(``PlainParallelEnv`` in tests/envs/plain_paths.py: the step as first written over the
plain core and ``concatenate([state_features, patch(groups)])``): the same seeds and
actions give the same reset and step outputs, bit for bit and in the same key order —
observations (dtype, shape, bytes, writable), rewards, terminations, truncations, every
info value — and the same agents and state, in both ``on_goal`` modes, with Dict and
flat observations, through arrivals, the end of the team's work and the horizon.

Runtime: about 3 s.
"""
from __future__ import annotations

import numpy as np
import pytest

from envs.warehouse_v0 import parallel_env
from tests.envs.plain_paths import PlainParallelEnv


def same_array(a: np.ndarray, b: np.ndarray) -> bool:
    return (a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
            and a.flags.writeable == b.flags.writeable)


def assert_same_obs(got: dict, want: dict, flat: bool) -> None:
    assert list(got) == list(want)
    for agent in want:
        if flat:
            assert same_array(got[agent], want[agent]), agent
        else:
            assert list(got[agent]) == list(want[agent]) == ["observation", "action_mask"]
            for key in want[agent]:
                assert same_array(got[agent][key], want[agent][key]), (agent, key)


def assert_same_flags(got: dict, want: dict) -> None:
    assert list(got.items()) == list(want.items())
    assert all(type(v) is type(w) for v, w in zip(got.values(), want.values(), strict=True))


def assert_same_infos(got: dict, want: dict) -> None:
    assert list(got) == list(want)
    for agent in want:
        g, w = got[agent], want[agent]
        assert list(g) == list(w), agent
        for key in w:
            if isinstance(w[key], np.ndarray):
                assert same_array(g[key], w[key]), (agent, key)
            else:
                assert type(g[key]) is type(w[key]) and g[key] == w[key], (agent, key)


def actions_for(obs: dict, agents: list[str], rng: np.random.Generator, flat: bool,
                greedy: float) -> dict:
    """Greedy (largest action progress) for a fraction ``greedy`` of the robots, random
    moves (some blocked) for the others: robots arrive, collide and try blocked moves."""
    acts = {}
    for a in agents:
        o = obs[a]
        feats, mask = (o[:-5], o[-5:]) if flat else (o["observation"], o["action_mask"])
        if rng.random() < greedy:
            acts[a] = int(np.argmax(np.where(mask > 0, feats[6:11], -9)))
        else:
            acts[a] = int(rng.integers(5))
    return acts


CASES = [
    dict(n_robots=6, groups=3, layout="tiny", horizon=40),
    dict(n_robots=20, layout="wh20", horizon=30, obs_radius=5),
    dict(n_robots=12, groups=1, layout="wh20", horizon=25, obs_radius=3, loss_p=0.5),
]


@pytest.mark.parametrize("flat_obs", [False, True])
@pytest.mark.parametrize("on_goal", ["remove", "stay"])
@pytest.mark.parametrize("case", range(len(CASES)))
def test_step__equals_the_plain_step_bit_for_bit(case, on_goal, flat_obs):
    cfg = dict(CASES[case], on_goal=on_goal, flat_obs=flat_obs)
    fast, plain = parallel_env(**cfg), PlainParallelEnv(**cfg)
    rng = np.random.default_rng(case)
    seen = set()
    for episode in range(4):
        options = None
        if episode == 3:  # robot 0 starts on its goal (done at t = 0)
            s, g = fast.layout.cells[[0, 1, 2]], fast.layout.cells[[0, 3, 4]]
            n = cfg["n_robots"]
            sample = plain.layout.cells[np.arange(5, 5 + 2 * (n - 3))]
            options = {"starts": [tuple(x) for x in np.concatenate([s, sample[: n - 3]])],
                       "goals": [tuple(x) for x in np.concatenate([g, sample[n - 3:]])]}
        obs, infos = fast.reset(seed=episode, options=options)
        obs_p, infos_p = plain.reset(seed=episode, options=options)
        assert_same_obs(obs, obs_p, flat_obs)
        assert_same_infos(infos, infos_p)
        while fast.agents:
            acts = actions_for(obs, fast.agents, rng, flat_obs, (0.8, 0.1, 0.95, 0.8)[episode])
            obs, rew, term, trunc, infos = fast.step(acts)
            obs_p, rew_p, term_p, trunc_p, infos_p = plain.step(dict(acts))
            assert_same_obs(obs, obs_p, flat_obs)
            assert_same_flags(rew, rew_p)
            assert_same_flags(term, term_p)
            assert_same_flags(trunc, trunc_p)
            assert_same_infos(infos, infos_p)
            assert fast.agents == plain.agents
            assert same_array(fast.state(), plain.state())
            seen.update(k for k, v in [("arrival", any(term.values()) and fast.agents),
                                       ("all_done", any(term.values()) and not fast.agents),
                                       ("horizon", any(trunc.values())),
                                       ("collision", any(i["collision"] for i in infos.values()))]
                        if v)
    assert {"collision", "horizon"} <= seen, seen
    if on_goal == "remove":
        assert "arrival" in seen, seen
    if case == 0:
        assert "all_done" in seen, seen
