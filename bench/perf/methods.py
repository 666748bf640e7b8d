"""Training throughput of any registered method, and the hierarchical safety filter's cost.

* ``measure_training``: trains a method from the registry for a few updates and reports
  env-steps/s (episode-steps of training, rollout + update, per second of wall time on one
  torch thread), agent-steps/s (x N), and the projected time of one paper cell (2000
  episodes x 500 steps) at that throughput, from wall time and from process CPU time (the
  latter is what one dedicated core would take when the machine is shared). Untrained policies rarely finish early, so
  the episodes run near the full horizon: the projection is an upper bound for a run
  whose policy improves.
* ``measure_filter``: the hierarchical method's rollout (untrained, sampled proposals;
  the filter is busier than with a trained policy) with every safety-filter call timed:
  microseconds per group-step, mean candidates examined, fallback and correction rates.
* ``run_hierarchical_suite``: both at N = 20 (wh20) and N = 100 (the wh100 preset and
  the MovingAI warehouse map, whose density matches the paper's Table I).
* ``measure_cell_training`` / ``run_train_suite`` (``bench perf --suite train``): what a
  bench cell pays per update, every learned method at N = 40 and N = 100 on the MovingAI
  map: whole ``train_iteration()`` calls (scenario sampling and reset, rollout, update)
  after a warm-up, in env-steps/s of wall time and of process CPU time; and the achieved
  matmul FLOP/s of a training iteration against this core's measured peaks at the same
  shapes and at large shapes, fp32 and bf16, all measured in the same run (bench/perf/flops.py).

    .venv/bin/python -m bench.perf.methods          # prints the table
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch

from algorithms.common.episodes import TRAIN_STREAM, EpisodeBatch, batch_rng
from algorithms.common.execution import ActionChoice
from algorithms.common.seed_stack import train_stacked
from algorithms.registry import method_class
from bench.perf import budget
from bench.perf.timing import time_training
from envs.config import EnvConfig
from envs.layouts import MAPS_DIR

REAL_MAP = MAPS_DIR / "warehouse-10-20-10-2-1.map"  # bundled copy of the MovingAI map


def measure_training(method: str, n_robots: int, layout: str, iterations: int = 1,
                     batch_episodes: int = 8, horizon: int = budget.HORIZON, loss_p: float = 0.2,
                     seed: int = 0, **params: Any) -> dict[str, Any]:
    """Throughput of ``iterations`` training updates of ``method`` (one torch thread)."""
    torch.set_num_threads(1)
    env = EnvConfig.make(n_robots=n_robots, layout=layout, horizon=horizon, loss_p=loss_p,
                         groups=min(4, n_robots))
    m = method_class(method)(env, {"batch_episodes": batch_episodes, **params}, seed=seed)
    cpu0 = time.process_time()
    t = time_training(m, iterations)
    cpu = time.process_time() - cpu0
    total = t["rollout_s"] + t["update_s"]
    steps = max(t["episode_steps"], 1)
    return {
        "method": method, "n_robots": n_robots, "layout": Path(layout).stem,
        "batch_episodes": batch_episodes, "episode_steps": t["episode_steps"],
        "env_steps_per_s": steps / total,
        "agent_steps_per_s": n_robots * steps / total,
        "rollout_ms_per_step": 1e3 * t["rollout_s"] / max(t["batched_steps"], 1),
        "update_ms_per_step": 1e3 * t["update_s"] / max(t["batched_steps"], 1),
        "paper_cell_train_min": total / steps * budget.EPISODES * budget.HORIZON / 60,
        # Process CPU time: what one dedicated core would take on a shared, busy machine.
        "paper_cell_train_min_cpu": cpu / steps * budget.EPISODES * budget.HORIZON / 60,
    }


LEARNED = ("hierarchical", "decentralized", "ic3net")
TRAIN_SIZES = (40, 100)


def measure_cell_training(method: str, n_robots: int, layout: str, iterations: int = 2,
                          warmup: int = 1, batch_episodes: int = 8, horizon: int = 200,
                          loss_p: float = 0.2, seed: int = 0, stack: int = 1, **params: Any) -> dict[str, Any]:
    """Throughput of whole training updates as a cell runs them (one torch thread).

    ``warmup`` updates run first (one-time costs: torch kernels, the layout's distance
    table); then ``iterations`` timed ``train_iteration()`` calls. Rates per second of
    wall time and of process CPU time (one dedicated core on a shared, busy machine).
    ``stack`` > 1: that many seeds of the cell trained seed-stacked (``bench run
    --stack-seeds``), the rates per cell (env-steps of all seeds over the time of all).
    """
    torch.set_num_threads(1)
    env = EnvConfig.make(n_robots=n_robots, layout=layout, horizon=horizon, loss_p=loss_p,
                         groups=min(4, n_robots))
    cls = method_class(method)
    ms = [cls(env, {"batch_episodes": batch_episodes, **params}, seed=seed + k) for k in range(stack)]
    view = cls.stack_view(ms) if stack > 1 else None

    def update() -> int:
        out = train_stacked(ms, view) if view is not None else [ms[0].train_iteration()]
        return int(sum(r["steps"] for rows in out for r in rows))

    for _ in range(warmup):
        update()
    steps = 0
    wall0, cpu0 = time.perf_counter(), time.process_time()
    for _ in range(iterations):
        steps += update()
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    steps = max(steps, 1)
    return {
        "method": method, "n_robots": n_robots, "layout": Path(layout).stem, "stacked_seeds": stack,
        "batch_episodes": batch_episodes, "horizon": horizon, "episode_steps": steps,
        "env_steps_per_s": steps / wall, "env_steps_per_s_cpu": steps / cpu,
        "agent_steps_per_s": n_robots * steps / wall, "agent_steps_per_s_cpu": n_robots * steps / cpu,
        "paper_cell_train_min": wall / steps * budget.EPISODES * budget.HORIZON / 60,
        "paper_cell_train_min_cpu": cpu / steps * budget.EPISODES * budget.HORIZON / 60,
    }


def run_train_suite(iterations: int = 2, horizon: int = 200, batch_episodes: int = 8,
                    sizes: tuple[int, ...] = TRAIN_SIZES, methods: tuple[str, ...] = LEARNED,
                    layout: str | None = None, stack: int = 3, flops: bool = True) -> pd.DataFrame:
    """Training env-steps/s per cell of every learned method at N = 40 and 100 (MovingAI map),
    and of ``stack`` seeds trained seed-stacked for the methods that stack (every learned one);
    with ``flops``, each unstacked row's matmul FLOP/s and its fraction of this core's
    peaks (bench/perf/flops.py)."""
    where = layout or str(REAL_MAP)
    cases = [(name, n, 1) for name in methods for n in sizes]
    if stack > 1:
        cases += [(name, n, stack) for name in methods for n in sizes
                  if method_class(name).stackable({"batch_episodes": batch_episodes})]
    rows = [measure_cell_training(name, n, where, iterations=iterations, horizon=horizon,
                                  batch_episodes=batch_episodes, stack=k)
            for name, n, k in cases]
    if flops:  # achieved matmul FLOP/s against this core's peaks (bench/perf/flops.py)
        from bench.perf.flops import machine_peaks, matmul_rates

        peaks = machine_peaks()  # fp32 and bf16, measured in this run
        for r in rows:
            if r["stacked_seeds"] == 1:
                r.update(matmul_rates(r["method"], r["n_robots"], where, r["env_steps_per_s_cpu"], peaks["fp32"],
                                      horizon=horizon, batch_episodes=batch_episodes, peak_bf16=peaks["bf16"]))
    return pd.DataFrame([{"suite": "train", **r} for r in rows])


class _TimedFilter:
    """Wraps a SafetyFilter, accumulating wall time and outcomes of every call."""

    def __init__(self, inner: Any) -> None:
        self.inner, self.seconds, self.group_steps = inner, 0.0, 0
        self.examined: list[np.ndarray] = []
        self.fallback: list[np.ndarray] = []
        self.corrected = self.controlled = 0

    def blocked_cells(self, *args: Any) -> np.ndarray:
        t0 = time.perf_counter()
        out = self.inner.blocked_cells(*args)
        self.seconds += time.perf_counter() - t0
        return out

    def __call__(self, pos: np.ndarray, occupies: np.ndarray, controlled: np.ndarray,
                 proposal: np.ndarray, logp: np.ndarray, blocked: np.ndarray) -> Any:
        t0 = time.perf_counter()
        res = self.inner(pos, occupies, controlled, proposal, logp, blocked)
        self.seconds += time.perf_counter() - t0
        called = res.called
        self.group_steps += int(called.sum())
        self.examined.append(res.examined[called])
        self.fallback.append(res.fallback[called])
        ctl = controlled & occupies
        self.corrected += int(((res.actions != proposal) & ctl).sum())
        self.controlled += int(ctl.sum())
        return res


def measure_filter(n_robots: int, layout: str, horizon: int = 100, batch_episodes: int = 8,
                   loss_p: float = 0.2, search_radius: int = budget.SEARCH_RADIUS, c_max: int = budget.C_MAX,
                   seed: int = 0) -> dict[str, Any]:
    """Safety-filter cost in one rollout of the (untrained) hierarchical method."""
    torch.set_num_threads(1)
    env = EnvConfig.make(n_robots=n_robots, layout=layout, horizon=horizon, loss_p=loss_p)
    # Any: the method's own `filter` attribute (not part of the Method contract) is swapped
    # for a timed wrapper.
    m: Any = method_class("hierarchical")(env, {"search_radius": search_radius, "c_max": c_max}, seed=seed)
    timed = _TimedFilter(m.filter)
    m.filter = timed
    batch = EpisodeBatch(env, batch_episodes, batch_rng(seed, TRAIN_STREAM, 0), m.layout)
    with torch.no_grad():
        m.run(batch, ActionChoice.train(m.torch_gen))
    examined = np.concatenate(timed.examined) if timed.examined else np.zeros(0)
    fallback = np.concatenate(timed.fallback) if timed.fallback else np.zeros(0)
    return {
        "n_robots": n_robots, "layout": Path(layout).stem, "group_steps": timed.group_steps,
        "filter_us_per_group_step": 1e6 * timed.seconds / max(timed.group_steps, 1),
        "mean_candidates": float(examined.mean()) if examined.size else float("nan"),
        "fallback_rate": float(fallback.mean()) if fallback.size else float("nan"),
        "correction_rate": timed.corrected / max(timed.controlled, 1),
    }


def run_hierarchical_suite(iterations: int = 1, horizon: int = budget.HORIZON) -> pd.DataFrame:
    """Rows for N = 20 and N = 100: training throughput, projected paper-cell time, and
    safety-filter cost per group-step."""
    cases = [(20, "wh20"), (100, "wh100")]
    if REAL_MAP.exists():
        cases.append((100, str(REAL_MAP)))
    rows = []
    for n, layout in cases:
        row = measure_training("hierarchical", n, layout, iterations=iterations, horizon=horizon)
        filt = measure_filter(n, layout)
        row.update({k: filt[k] for k in ("filter_us_per_group_step", "mean_candidates",
                                          "fallback_rate", "correction_rate")})
        rows.append({"suite": "hierarchical", **row})
    return pd.DataFrame(rows)


if __name__ == "__main__":
    with pd.option_context("display.width", 200, "display.max_columns", 30):
        print(run_hierarchical_suite().round(3).to_string(index=False))
