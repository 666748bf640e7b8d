"""Timing of training updates shared by the perf suites: ``time_training`` (rollout and
update timed apart) and the size of one paper cell the suites project their times to
(2000 training episodes and 100 evaluation episodes of 500 steps).

May import: envs, algorithms (it times any ``Method``).
"""
from __future__ import annotations

import time

import torch

from algorithms.base import Method
from algorithms.common.episodes import TRAIN_STREAM, EpisodeBatch, batch_rng
from algorithms.common.execution import ActionChoice


def time_training(method: Method, iterations: int = 1) -> dict[str, float]:
    """Time ``iterations`` training updates of ``method``, rollout and update apart."""
    rollout_s = update_s = 0.0
    batched_steps = episode_steps = 0
    for _ in range(iterations):
        rng = batch_rng(method.seed, TRAIN_STREAM, method.iterations)
        batch = EpisodeBatch(method.env, method.params.batch_episodes, rng, method.layout)
        t0 = time.perf_counter()
        with torch.no_grad():
            state, rows = method.run(batch, ActionChoice.train(method.torch_gen))
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
