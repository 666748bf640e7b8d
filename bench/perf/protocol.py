"""Training cost of ``protocol = "mappo"`` against ``"paper"`` per env-step (``bench perf
--suite protocol``; the bound is 1.3x, docs/decisions/0201).

For every learned method, both protocols of the method on one configuration (the MovingAI
map, p = 0.2, the paper's batch of 8 episodes) in one process, alternating whole
``train_iteration()`` calls (rollout and update) after a warm-up of each, so machine load
hits both alike. Process CPU seconds per env-step of each protocol and their ratio; the
wall-time ratio beside it.

May import: algorithms (registry), envs, bench.perf (methods).
"""
from __future__ import annotations

import time
from typing import Any

import pandas as pd
import torch

from algorithms.registry import method_class
from bench.perf.methods import LEARNED, REAL_MAP
from envs.config import EnvConfig

PROTOCOLS = ("paper", "mappo")


def measure_protocol_cost(method: str, n_robots: int = 40, horizon: int = 200, iterations: int = 3,
                          batch_episodes: int = 8, seed: int = 0, layout: str | None = None) -> dict[str, Any]:
    """CPU and wall seconds per env-step of ``iterations`` interleaved training updates of
    each protocol (one torch thread), after one warm-up update of each."""
    torch.set_num_threads(1)
    env = EnvConfig.make(n_robots=n_robots, layout=layout or str(REAL_MAP), horizon=horizon, loss_p=0.2,
                         groups=min(4, n_robots))
    methods = {pr: method_class(method)(env, {"batch_episodes": batch_episodes, "protocol": pr}, seed=seed)
               for pr in PROTOCOLS}
    for m in methods.values():
        m.train_iteration()
    spent = {pr: {"cpu": 0.0, "wall": 0.0, "steps": 0} for pr in PROTOCOLS}
    for _ in range(iterations):
        for pr, m in methods.items():
            wall0, cpu0 = time.perf_counter(), time.process_time()
            rows = m.train_iteration()
            spent[pr]["cpu"] += time.process_time() - cpu0
            spent[pr]["wall"] += time.perf_counter() - wall0
            spent[pr]["steps"] += int(sum(r["steps"] for r in rows))
    per = {pr: {k: s[k] / max(s["steps"], 1) for k in ("cpu", "wall")} for pr, s in spent.items()}
    return {"method": method, "n_robots": n_robots, "horizon": horizon, "batch_episodes": batch_episodes,
            "updates": iterations,
            **{f"{pr}_ms_per_step_cpu": 1e3 * per[pr]["cpu"] for pr in PROTOCOLS},
            "ratio_cpu": per["mappo"]["cpu"] / per["paper"]["cpu"],
            "ratio_wall": per["mappo"]["wall"] / per["paper"]["wall"]}


def run_protocol_suite(sizes: tuple[int, ...] = (40, 80), methods: tuple[str, ...] = LEARNED,
                       **kwargs: Any) -> pd.DataFrame:
    """``measure_protocol_cost`` for every learned method at N = 40 and 80."""
    return pd.DataFrame([{"suite": "protocol", **measure_protocol_cost(name, n, **kwargs)}
                         for name in methods for n in sizes])


if __name__ == "__main__":
    with pd.option_context("display.width", 200, "display.precision", 3):
        print(run_protocol_suite().to_string(index=False))
