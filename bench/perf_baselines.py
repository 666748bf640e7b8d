"""Training throughput of the learned baselines (decentralized, IC3Net) at N = 20 and 100.

``run_baselines_suite`` trains each baseline for ``iterations`` updates of
``batch_episodes`` episodes (horizon 500, the paper's, on the preset sized for N; an
untrained policy rarely finishes early, so episodes run close to the full horizon) and
times the rollout (decide + core step, no_grad) and the update separately. Columns:

* ``env_steps_per_s``: episode-steps per second of training (rollout and update);
* ``robot_steps_per_s``: the same times N;
* ``rollout_ms_per_step`` / ``update_ms_per_step``: per batched step (B episodes at once);
* ``paper_cell_train_min``: projected wall time of one paper cell's training (2000
  episodes of 500 steps) at this throughput, one core;
* ``paper_cell_eval_min``: projected time of its 100 evaluation episodes (rollout only).

    .venv/bin/python -m bench.perf_baselines          # prints the table
"""
from __future__ import annotations

import time

import pandas as pd
import torch

from algorithms.base import Method
from algorithms.common.episodes import TRAIN_STREAM, EpisodeBatch, batch_rng
from algorithms.registry import method_class
from envs.config import EnvConfig
from envs.layouts import preset_for

PAPER_EPISODES, PAPER_HORIZON, PAPER_EVAL_EPISODES = 2000, 500, 100
BASELINES = ("decentralized", "ic3net")


def time_training(method: Method, iterations: int = 1) -> dict[str, float]:
    """Time ``iterations`` training updates of ``method``, rollout and update apart."""
    rollout_s = update_s = 0.0
    batched_steps = episode_steps = 0
    for _ in range(iterations):
        rng = batch_rng(method.seed, TRAIN_STREAM, method.iterations)
        batch = EpisodeBatch(method.env, method.params.batch_episodes, rng, method.layout)
        t0 = time.perf_counter()
        with torch.no_grad():
            state, rows = method.run(batch, greedy=False)
        t1 = time.perf_counter()
        method.update(state)
        t2 = time.perf_counter()
        method.iterations += 1
        rollout_s += t1 - t0
        update_s += t2 - t1
        batched_steps += batch.core.t
        episode_steps += int(sum(r["steps"] for r in rows))
    return {"rollout_s": rollout_s, "update_s": update_s, "batched_steps": batched_steps,
            "episode_steps": episode_steps}


def measure(name: str, n: int, batch_episodes: int = 8, iterations: int = 1,
            horizon: int = PAPER_HORIZON, seed: int = 0) -> dict[str, float | int | str]:
    layout = preset_for(n)
    env = EnvConfig.make(n_robots=n, layout=layout, groups=min(4, n), horizon=horizon, loss_p=0.2)
    method = method_class(name)(env, {"batch_episodes": batch_episodes}, seed=seed)
    t = time_training(method, iterations)
    total = t["rollout_s"] + t["update_s"]
    per_episode_step = total / t["episode_steps"]
    rollout_per_episode_step = t["rollout_s"] / t["episode_steps"]
    return {
        "suite": "baselines", "method": name, "n_robots": n, "layout": layout,
        "batch_episodes": batch_episodes, "episode_steps": t["episode_steps"],
        "env_steps_per_s": t["episode_steps"] / total,
        "robot_steps_per_s": n * t["episode_steps"] / total,
        "rollout_ms_per_step": 1e3 * t["rollout_s"] / t["batched_steps"],
        "update_ms_per_step": 1e3 * t["update_s"] / t["batched_steps"],
        "paper_cell_train_min": per_episode_step * PAPER_EPISODES * PAPER_HORIZON / 60,
        "paper_cell_eval_min": rollout_per_episode_step * PAPER_EVAL_EPISODES * PAPER_HORIZON / 60,
    }


def run_baselines_suite(sizes: tuple[int, ...] = (20, 100), iterations: int = 1) -> pd.DataFrame:
    """One row per (baseline, N): training throughput and projected paper-cell time."""
    torch.set_num_threads(1)
    return pd.DataFrame([measure(name, n, iterations=iterations)
                         for name in BASELINES for n in sizes])


if __name__ == "__main__":
    print(run_baselines_suite().to_string(index=False))
