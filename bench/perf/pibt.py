"""PIBT planner speed: milliseconds per step at N = 100 on the real map and on ``wh100``.

``run_pibt_suite`` runs whole evaluation-like episodes (horizon 500, ``on_goal="remove"``)
of B episodes batched together and times the planner (``PIBTMethod.decide``) and the core
(``WarehouseCore.step``) separately. Columns:

* ``ms_per_step``: planner time per episode-step over whole episodes (robots leave the
  floor as they arrive, so later steps plan fewer robots) — what a cell costs;
* ``ms_per_step_full``: planner time per episode-step over the first ``full_steps`` steps
  of each episode, when (nearly) all N robots plan — comparable with the reference's
  "about 2 ms/step for 100 agents" (REFERENCES.md, pure Python pypibt);
* ``us_per_agent_step``: planner time per planned robot-step;
* ``env_ms_per_step``: core step time per episode-step;
* ``paper_cell_eval_s``: projected wall time of one paper cell's evaluation (100 episodes,
  planner + core, at this batch size); PIBT has no training.

    .venv/bin/python -m bench.perf.pibt          # markdown table
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd

from algorithms.common.episodes import EVAL_STREAM, EpisodeBatch, batch_rng
from algorithms.common.execution import ActionChoice
from algorithms.pibt import PIBTMethod
from bench.perf import budget
from envs.config import EnvConfig
from envs.layouts import MAPS_DIR

REAL_MAP = MAPS_DIR / "warehouse-10-20-10-2-1.map"  # bundled copy of the MovingAI map


def time_pibt(
    layout: str, n: int, batch: int, target_seconds: float, full_steps: int = 10, seed: int = 0,
) -> dict[str, float | int | str]:
    """Time PIBT on fresh batches of ``batch`` episodes until ``target_seconds`` of planning."""
    config = EnvConfig.make(n_robots=n, layout=layout, groups=min(4, n), horizon=500)
    method = PIBTMethod(config, seed=seed)
    plan_s = env_s = full_s = 0.0
    ep_steps = full_ep_steps = agent_steps = episodes = 0
    success = []
    chunk = 0
    while plan_s < target_seconds or episodes == 0:
        b = EpisodeBatch(config, batch, batch_rng(seed, EVAL_STREAM, chunk), method.layout)
        chunk += 1
        choice = ActionChoice.evaluate("planner")
        core, state = b.core, method.begin(b, choice)
        while b.running:
            running = int((~core.ended).sum())
            planning = int((~core.done & ~core.ended[:, None]).sum())
            t0 = time.perf_counter()
            dec = method.decide(b, state, choice)
            t1 = time.perf_counter()
            res = core.step(dec.actions)
            env_s += time.perf_counter() - t1
            method.observe(b, state, res)
            plan_s += t1 - t0
            ep_steps += running
            agent_steps += planning
            if core.t <= full_steps:
                full_s += t1 - t0
                full_ep_steps += running
        episodes += batch
        success.extend(core.done.mean(axis=1).tolist())
    per_ep_step = (plan_s + env_s) / ep_steps
    return {
        "layout": Path(layout).stem if layout.endswith(".map") else layout,
        "n_robots": n,
        "batch": batch,
        "episodes": episodes,
        "mean_steps": ep_steps / episodes,
        "success_rate": float(np.mean(success)),
        "ms_per_step": 1e3 * plan_s / ep_steps,
        "ms_per_step_full": 1e3 * full_s / max(full_ep_steps, 1),
        "us_per_agent_step": 1e6 * plan_s / max(agent_steps, 1),
        "env_ms_per_step": 1e3 * env_s / ep_steps,
        "paper_cell_eval_s": budget.EVAL_EPISODES * (ep_steps / episodes) * per_ep_step,
    }


def run_pibt_suite(
    n_robots: int = 100, batches: tuple[int, ...] = (1, 10), target_seconds: float = 2.0,
    seed: int = 0,
) -> pd.DataFrame:
    """One row per (layout, batch): the real MovingAI map and preset ``wh100`` at N robots."""
    rows = [
        time_pibt(layout, n_robots, b, target_seconds, seed=seed)
        for layout in (str(REAL_MAP), "wh100")
        for b in batches
    ]
    return pd.DataFrame(rows)


if __name__ == "__main__":
    with pd.option_context("display.width", 200, "display.precision", 3):
        print(run_pibt_suite().to_string(index=False))
