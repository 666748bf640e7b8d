"""SuperSuit + Stable-Baselines3 on warehouse_v0, and the PPO recipe of docs/interop.md
(tests/interop/recipe_sb3.py) learning on the tiny layout."""
from __future__ import annotations

import numpy as np
import pytest

ss = pytest.importorskip("supersuit")
pytest.importorskip("stable_baselines3")

from envs.errors import BenchError  # noqa: E402
from envs.warehouse_v0 import parallel_env  # noqa: E402
from tests.interop.recipe_sb3 import arrived, make_env, train  # noqa: E402

TINY = dict(n_robots=4, layout="tiny", horizon=40)


def test_sb3__vector_env_runs_through_episode_ends():
    vec = ss.pettingzoo_env_to_vec_env_v1(make_env(**TINY))
    vec = ss.concat_vec_envs_v1(vec, 2, num_cpus=0, base_class="stable_baselines3")
    vec.venv.reset(seed=0)
    rng = np.random.default_rng(0)
    dones, terminal = 0, 0
    for _ in range(100):  # horizon 40: at least two resets of each copy
        obs, rew, done, infos = vec.step(rng.integers(0, 5, size=8))
        assert obs.shape == (8, vec.observation_space.shape[0]) and obs.dtype == np.float32
        dones += int(done.sum())
        terminal += sum("terminal_observation" in info for info in infos)  # written into ours
    assert dones >= 16 and terminal == dones


def test_sb3__remove_mode_without_black_death_fails_clearly_in_supersuit():
    # Why the recipe uses on_goal="stay": SuperSuit's vector env needs a fixed agent set.
    layout_env = parallel_env(n_robots=2, layout="tiny", horizon=10, flat_obs=True)
    vec = ss.pettingzoo_env_to_vec_env_v1(layout_env)
    vec.reset(options={"starts": [(1, 1), (1, 2)], "goals": [(1, 1), (7, 11)]})
    with pytest.raises(AssertionError, match="black_death"):
        vec.step(np.array([4, 4]))


def test_sb3__black_death_of_supersuit_3_11_never_ends_the_episode_and_we_say_so():
    # supersuit 3.11.0 ends a black_death episode only if every agent is terminated AND
    # truncated (fixed upstream, Farama-Foundation/SuperSuit#265); our env refuses the
    # step after the end instead of returning empty dicts forever.
    env = ss.black_death_v3(parallel_env(n_robots=2, layout="tiny", horizon=2, flat_obs=True))
    env.reset(seed=0)
    for _ in range(2):
        env.step({"robot_0": 4, "robot_1": 4})
    with pytest.raises(BenchError, match="episode ended"):
        env.step({"robot_0": 4, "robot_1": 4})


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0])
def test_sb3__ppo_recipe_learns_on_tiny(seed):
    # Budget 20,000 agent-steps, about a minute on one loaded core.
    before = arrived(train(0, seed, **TINY), episodes=20, seed=1000, **TINY)
    after = arrived(train(20_000, seed, **TINY), episodes=20, seed=1000, **TINY)
    assert after > before + 0.2, (before, after)

