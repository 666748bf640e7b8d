"""Time POGEMA and RWARE on given grids; run inside .anchors-venv (``make anchors``).

Reads one JSON object on stdin::

    {"cases": [{"sim": "pogema" | "pogema_pettingzoo" | "rware", "layout": "wh100", "grid": ["..#.", ...],
                "n_agents": 100, "steps": 500, "target_seconds": 1.0, "seed": 0}, ...]}

``grid`` rows use ``.`` for free and ``#`` for blocked cells. Prints one JSON list on
stdout, one record per case. Like ``bench/perf/env.py`` for our core: episodes of
``steps`` steps with uniformly random actions drawn before the clock starts, each from an
untimed reset, until ``target_seconds`` of stepping (CPU seconds) have been timed. Imports nothing from
this project: it runs with POGEMA's pinned numpy/pydantic/gymnasium.
"""
from __future__ import annotations

import json
import sys
import time

import numpy as np

CLOCK = time.process_time  # CPU seconds, as bench/perf/env.py times our rows


def timed_episodes(env, case: dict, convert) -> tuple[int, float]:
    """(timed steps, timed seconds) over fresh episodes until the time target is met."""
    n, steps = case["n_agents"], case["steps"]
    rng = np.random.default_rng(case["seed"])
    total_steps, total_time, episode = 0, 0.0, 0
    while total_time < case["target_seconds"] or total_steps == 0:
        env.reset(seed=case["seed"] + episode)
        actions = [convert(a) for a in rng.integers(0, 5, size=(steps, n)).tolist()]
        t0 = CLOCK()
        for a in actions:
            env.step(a)
        total_time += CLOCK() - t0
        total_steps += steps
        episode += 1
    return total_steps, total_time


COLLISION_SYSTEM = "soft"  # ours = POGEMA soft without lowest-index-wins (docs/decisions/0003)


def pogema_config(case: dict):
    from pogema import GridConfig

    return GridConfig(
        map="\n".join(case["grid"]), num_agents=case["n_agents"], seed=case["seed"],
        max_episode_steps=case["steps"] + 1, obs_radius=5, on_target="finish",
        collision_system=COLLISION_SYSTEM,
    )


def time_pogema(case: dict) -> dict:
    import pogema
    from pogema import pogema_v0

    env = pogema_v0(grid_config=pogema_config(case))
    done, secs = timed_episodes(env, case, lambda a: a)
    return dict(
        version=pogema.__version__, steps=done, seconds=secs,
        settings=f"pogema_v0, obs_radius=5, on_target=finish, collision_system={COLLISION_SYSTEM}",
    )


def time_pogema_pettingzoo(case: dict) -> dict:
    """POGEMA's own PettingZoo wrapper, driven like ours in bench/perf/env.py: one dict of
    all N agents' actions per step, episodes stopped when no agent is left."""
    import pogema
    from pogema.integrations.pettingzoo import parallel_env

    env = parallel_env(pogema_config(case))
    names = env.possible_agents
    n, steps = case["n_agents"], case["steps"]
    rng = np.random.default_rng(case["seed"])
    total_steps, total_time, episode = 0, 0.0, 0
    while total_time < case["target_seconds"] or total_steps == 0:
        env.reset(seed=case["seed"] + episode)
        actions = [dict(zip(names, a, strict=True))
                   for a in rng.integers(0, 5, size=(steps, n)).tolist()]
        t0 = CLOCK()
        done = 0
        for a in actions:
            if not env.agents:
                break
            env.step(a)
            done += 1
        total_time += CLOCK() - t0
        total_steps += done
        episode += 1
    return dict(
        version=pogema.__version__, steps=total_steps, seconds=total_time,
        settings=f"pogema.integrations.pettingzoo.parallel_env, obs_radius=5, on_target=finish, "
                 f"collision_system={COLLISION_SYSTEM}",
    )


def rware_layout(grid: list[str]) -> str:
    """Blocked cells become shelves ``x``; two free cells of the last free row are goals."""
    rows = [row.replace("#", "x") for row in grid]
    for r in range(len(rows) - 1, -1, -1):
        free = [c for c, ch in enumerate(rows[r]) if ch == "."]
        if len(free) >= 2:
            row = list(rows[r])
            for c in free[:2]:
                row[c] = "g"
            rows[r] = "".join(row)
            break
    return "\n".join(rows)


def time_rware(case: dict) -> dict:
    from importlib.metadata import version

    from rware.warehouse import RewardType, Warehouse

    n, steps = case["n_agents"], case["steps"]
    layout = rware_layout(case["grid"])
    env = Warehouse(
        shelf_columns=1, column_height=1, shelf_rows=1, n_agents=n, msg_bits=0,
        sensor_range=1, request_queue_size=min(n, layout.count("x")),
        max_inactivity_steps=None, max_steps=steps + 1, reward_type=RewardType.INDIVIDUAL,
        layout=layout,
    )
    done, secs = timed_episodes(env, case, tuple)
    return dict(
        version=version("rware"), steps=done, seconds=secs,
        settings="Warehouse(layout=grid, shelves on blocked cells), sensor_range=1, flattened obs",
    )


def main() -> None:
    request = json.load(sys.stdin)
    out = []
    for case in request["cases"]:
        timer = {"pogema": time_pogema, "pogema_pettingzoo": time_pogema_pettingzoo,
                 "rware": time_rware}[case["sim"]]
        rec = timer(case)
        env_steps = rec["steps"] / rec["seconds"]
        out.append(dict(
            sim=case["sim"], layout=case["layout"], n_robots=case["n_agents"], batch=1,
            env_steps_per_s=env_steps,
            agent_steps_per_s=env_steps * case["n_agents"], **rec,
        ))
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
