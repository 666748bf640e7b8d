"""Stable-Baselines3 PPO on warehouse_v0 through SuperSuit (PettingZoo's SB3 tutorial recipe;
docs/interop.md; tests/interop/test_sb3.py runs exactly this file)."""
import numpy as np
import supersuit as ss
from stable_baselines3 import PPO
from stable_baselines3.common.utils import set_random_seed

from envs.warehouse_v0 import parallel_env


def make_env(**config):
    # on_goal="stay": every robot stays in `agents` until the episode ends (the fixed agent
    # set SuperSuit's vector env needs); flat_obs=True: one Box (features + action mask).
    return parallel_env(on_goal="stay", flat_obs=True, **config)


def train(steps: int, seed: int, **config) -> PPO:
    vec = ss.pettingzoo_env_to_vec_env_v1(make_env(**config))  # one sub-env per robot
    vec = ss.concat_vec_envs_v1(vec, 2, num_cpus=0, base_class="stable_baselines3")
    # SuperSuit's vector env has no seed(), which PPO(seed=...) calls: seed the envs
    # through the inner vector env and torch/numpy with set_random_seed instead.
    vec.venv.reset(seed=seed)
    set_random_seed(seed)
    model = PPO("MlpPolicy", vec, n_steps=128, batch_size=256, learning_rate=1e-3,
                ent_coef=0.01, verbose=0)
    return model.learn(total_timesteps=steps)


def arrived(model: PPO, episodes: int, seed: int, **config) -> float:
    """Fraction of robots on their goal at the end, with sampled actions
    (deterministic=False: the greedy policy deadlocks robots facing each other)."""
    env = make_env(**config)
    hits = []
    for episode in range(episodes):
        obs, infos = env.reset(seed=seed + episode)
        while env.agents:
            names = env.agents
            acts, _ = model.predict(np.stack([obs[a] for a in names]), deterministic=False)
            obs, _, _, _, infos = env.step(dict(zip(names, acts.tolist(), strict=True)))
        hits.append(np.mean([info["at_goal"] for info in infos.values()]))
    return float(np.mean(hits))
