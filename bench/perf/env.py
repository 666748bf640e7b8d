"""Env throughput: our batched core against POGEMA and RWARE, measured in the same run.

``run_env_suite`` times ``WarehouseCore.step`` (mode ``core``) and the step plus the
per-robot features every learned method computes (mode ``core+obs``, a (2r+1)^2 patch
with r = 5 like POGEMA's default view) on the presets ``wh{N}`` and on the real MovingAI
map, for B = 1 and B = 64 episodes. Actions are uniform over 0..4 and drawn before the
clock starts; each timed segment is one episode of ``steps`` steps from a fresh
(untimed) reset, repeated until ``target_seconds`` of stepping have been timed, so robots
reaching goals do not thin out the floor as a long random walk would. ``seconds`` are
CPU seconds of the measuring process (``time.process_time``; single-threaded numpy with
OMP_NUM_THREADS=1), for ours and the anchors alike, so other jobs on a shared machine
do not count as our time.

Mode ``pettingzoo`` times our PettingZoo adapter ``envs.warehouse_v0`` (B = 1, patch
radius 5): the step with every agent's observation, mask, reward, flags and infos.

Anchors (one env, B = 1) run on the same grids in ``.anchors-venv`` (``make anchors``):
POGEMA ``pogema_v0`` (11x11 observations, ``on_target="finish"``, collision system
``soft``, the closest to ours: ours is POGEMA soft without its lowest-index-wins rule for
contested cells, docs/decisions/0003), POGEMA's PettingZoo wrapper (mode ``pettingzoo``,
same settings) and RWARE's ``Warehouse`` with blocked cells as shelves. ``vs_pogema`` is
a row's agent-steps/s over POGEMA's on the same layout and N (PettingZoo rows over
POGEMA's PettingZoo wrapper). Without the anchor venv the table holds our rows and
a note saying why the anchors are missing.

    .venv/bin/python -m bench.perf.env           # markdown table, then JSON
"""
from __future__ import annotations

import json
import os
import platform
import subprocess
import time
from pathlib import Path

import numpy as np
import pandas as pd

from envs.config import EnvConfig
from envs.core import WarehouseCore
from envs.layouts import MAPS_DIR, Layout, load_layout, preset_for
from envs.observations import PatchExtractor, robot_features
from envs.scenarios import sample_scenarios
from envs.warehouse_v0 import parallel_env

ROOT = Path(__file__).resolve().parents[2]
REAL_MAP = MAPS_DIR / "warehouse-10-20-10-2-1.map"  # bundled copy of the MovingAI map
ANCHORS_PY = ROOT / ".anchors-venv" / "bin" / "python"
ANCHORS_SCRIPT = Path(__file__).resolve().with_name("anchors_script.py")
OBS_RADIUS = 5
# CPU seconds of this process: on a shared machine other load does not count, and the
# anchor script (another process) is timed the same way.
CLOCK = time.process_time
COLUMNS = [
    "sim", "mode", "layout", "n_robots", "batch", "steps", "seconds", "env_steps_per_s",
    "agent_steps_per_s", "vs_pogema", "version", "note",
]


def time_core(
    layout: Layout, n: int, batch: int, steps: int, target_seconds: float,
    with_obs: bool, seed: int = 0,
) -> tuple[int, float]:
    """(timed steps, timed seconds) of ``batch`` episodes of ``n`` robots on ``layout``."""
    config = EnvConfig.make(n_robots=n, groups=min(4, n), horizon=steps)
    core = WarehouseCore(config, layout=layout)
    rng = np.random.default_rng(seed)
    patch = PatchExtractor(core, OBS_RADIUS) if with_obs else None
    total_steps, total_time = 0, 0.0
    while total_time < target_seconds or total_steps == 0:
        starts, goals = sample_scenarios(layout, n, batch, rng)
        core.reset(starts, goals)
        if patch is not None:
            patch = PatchExtractor(core, OBS_RADIUS)
        actions = rng.integers(0, 5, size=(steps, batch, n))
        t0 = CLOCK()
        if patch is None:
            for a in actions:
                core.step(a)
        else:
            for a in actions:
                core.step(a)
                robot_features(core, patch)
        total_time += CLOCK() - t0
        total_steps += steps
    return total_steps, total_time


def time_pettingzoo(
    layout: Layout, n: int, steps: int, target_seconds: float, seed: int = 0,
) -> tuple[int, float]:
    """(timed steps, timed seconds) through ``warehouse_v0.parallel_env`` (B = 1).

    What a user of the PettingZoo API pays per step: the core step, observations
    (radius ``OBS_RADIUS``, as POGEMA's) with action masks, rewards, terminations and
    infos for every live agent. Each step's action dict holds all N agents (finished
    agents' actions are ignored, as POGEMA's wrapper does), drawn before the clock.
    """
    env = parallel_env(n_robots=n, layout=layout, horizon=steps, obs_radius=OBS_RADIUS)
    rng = np.random.default_rng(seed)
    names = env.possible_agents
    total_steps, total_time, episode = 0, 0.0, 0
    while total_time < target_seconds or total_steps == 0:
        env.reset(seed=seed + episode)
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
    return total_steps, total_time


def run_anchors(
    cases: list[tuple[Layout, int]], steps: int, target_seconds: float, seed: int = 0,
) -> tuple[list[dict], str]:
    """POGEMA and RWARE rows from the anchor venv, or ([], a note saying why not)."""
    if not ANCHORS_PY.exists():
        return [], f"anchors not measured: {ANCHORS_PY.parent.parent.name} missing (run `make anchors`)"
    request = {"cases": [
        dict(sim=sim, layout=layout.name, n_agents=n, steps=steps, seed=seed,
             target_seconds=target_seconds,
             grid=["".join("#" if o else "." for o in row) for row in layout.obstacles])
        for layout, n in cases for sim in ("pogema", "pogema_pettingzoo", "rware")
    ]}
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run(
        [str(ANCHORS_PY), str(ANCHORS_SCRIPT)], input=json.dumps(request), text=True,
        capture_output=True, env=env, timeout=1800, check=False,
    )
    if proc.returncode != 0:
        last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        return [], f"anchors failed (exit {proc.returncode}): {last}"
    rows = json.loads(proc.stdout)
    for row in rows:
        row["mode"] = "pettingzoo" if row["sim"] == "pogema_pettingzoo" else "env"
        row["sim"] = row["sim"].replace("_pettingzoo", "")
        row["note"] = row.pop("settings")
    return rows, ""


def run_env_suite(
    ns: tuple[int, ...] = (20, 40, 60, 100),
    batches: tuple[int, ...] = (1, 64),
    steps: int = 500,
    include_anchors: bool = True,
    target_seconds: float = 1.0,
    real_map: str | Path | None = REAL_MAP,
    real_map_n: int = 100,
    with_obs: bool = True,
    with_pettingzoo: bool = True,
) -> pd.DataFrame:
    """Agent-steps/s and env-steps/s of our core (and the anchors) in one table.

    One row per (sim, mode, layout, N, B); columns ``COLUMNS``. ``steps`` is the episode
    length of each timed segment; each row times at least ``target_seconds``.
    """
    cases: list[tuple[Layout, int]] = [(load_layout(preset_for(n)), n) for n in ns]
    if real_map is not None and Path(real_map).exists():
        cases.append((load_layout(str(real_map)), real_map_n))
    version = f"numpy {np.__version__}, python {platform.python_version()}"
    rows: list[dict] = []
    for layout, n in cases:
        for batch in batches:
            for mode in ("core", "core+obs") if with_obs else ("core",):
                done, secs = time_core(layout, n, batch, steps, target_seconds, mode != "core")
                rows.append(dict(
                    sim="ours", mode=mode, layout=layout.name, n_robots=n, batch=batch,
                    steps=done, seconds=secs, env_steps_per_s=done * batch / secs,
                    agent_steps_per_s=done * batch * n / secs, version=version, note="",
                ))
        if with_pettingzoo:
            done, secs = time_pettingzoo(layout, n, steps, target_seconds)
            rows.append(dict(
                sim="ours", mode="pettingzoo", layout=layout.name, n_robots=n, batch=1,
                steps=done, seconds=secs, env_steps_per_s=done / secs,
                agent_steps_per_s=done * n / secs, version=version, note="",
            ))
    note = "anchors not requested"
    if include_anchors:
        anchor_rows, note = run_anchors(cases, steps, target_seconds)
        rows += anchor_rows
    df = pd.DataFrame(rows)
    if note:
        df.loc[df["sim"] == "ours", "note"] = note
    # Core rows compare with POGEMA's env, PettingZoo rows with POGEMA's PettingZoo wrapper.
    kind = {"pettingzoo": "pettingzoo"}
    pogema = {
        (r.layout, r.n_robots, r.mode): r.agent_steps_per_s
        for r in df.itertuples() if r.sim == "pogema"
    }
    keys = [(r.layout, r.n_robots, kind.get(r.mode, "env")) for r in df.itertuples()]
    df["vs_pogema"] = [
        r.agent_steps_per_s / pogema[k] if k in pogema else float("nan")
        for r, k in zip(df.itertuples(), keys, strict=True)
    ]
    return df.reindex(columns=COLUMNS)


def to_markdown(df: pd.DataFrame) -> str:
    """A plain markdown table (no tabulate dependency)."""
    shown = df.drop(columns=["version", "note"])
    fmt = {
        "seconds": "{:.2f}", "env_steps_per_s": "{:,.0f}", "agent_steps_per_s": "{:,.0f}",
        "vs_pogema": "{:.1f}x",
    }
    lines = ["| " + " | ".join(shown.columns) + " |", "|" + "---|" * len(shown.columns)]
    for row in shown.itertuples(index=False):
        cells = [
            fmt[c].format(v) if c in fmt and pd.notna(v) else ("" if pd.isna(v) else str(v))
            for c, v in zip(shown.columns, row, strict=True)
        ]
        lines.append("| " + " | ".join(cells) + " |")
    notes = sorted({n for n in df["note"] if n})
    return "\n".join(lines + [""] + [f"- {n}" for n in notes])


if __name__ == "__main__":
    table = run_env_suite()
    print(to_markdown(table))
    print()
    print(table.to_json(orient="records", indent=1))
