"""Synthetic result stores in the bench's schema (bench/store/schema.py), built to make the
paper's claims hold (``hold=True``) or fail (``hold=False``).

Cells: hierarchical at N in {20,40,60,80,90,100} x p in {0.2,0.4,0.6}; decentralized at
N in {20,40,60} x p = 0.2; IC3Net at N in {40,60} x every p. Training curves rise and
plateau (hierarchical above decentralized, gap widest at 60); evaluation success is
higher for hierarchical; payload is exactly N(Z-1)d_m and N(N-1)d_m; no collisions and
3% corrections, Table I's mean candidates and no fallback. ``hold=False`` reverses each of these.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from bench.store.run_store import RunStore
from bench.store.schema import SCHEMA_VERSION

D_M, Z = 3, 4
HIER_N = (20, 40, 60, 80, 90, 100)
PS = (0.2, 0.4, 0.6)


def cell_specs(seeds: int = 2) -> list[dict]:
    specs = []
    for s in range(seeds):
        specs += [dict(method="hierarchical", n_robots=n, loss_p=p, seed=s) for n in HIER_N for p in PS]
        specs += [dict(method="decentralized", n_robots=n, loss_p=0.2, seed=s) for n in (20, 40, 60)]
        specs += [dict(method="ic3net", n_robots=n, loss_p=p, seed=s) for n in (40, 60) for p in PS]
    return specs


def _train_curve(method: str, n: int, episodes: int, rng: np.random.Generator, hold: bool) -> np.ndarray:
    e = np.arange(episodes, dtype=np.float64)
    if method == "hierarchical":
        final = 10.0
        if not hold and n >= 80:  # keeps rising: no plateau
            return -5 + 15 * e / episodes + rng.normal(0, 0.3, episodes)
    else:
        final = {20: 8.0, 40: 7.0, 60: 2.0}.get(n, 5.0)
        if not hold:
            final = 12.0  # decentralized on top, no gap widening
    final += rng.normal(0, 0.3)  # seed-to-seed variation
    return -5 + (final + 5) * (1 - np.exp(-e / (0.15 * episodes))) + rng.normal(0, 0.3, episodes)


def smoke_specs(ns: tuple[int, ...] = (4, 8), p: float = 0.2) -> list[dict]:
    """Every method at small team sizes and one p, one seed: what a smoke run holds."""
    return [dict(method=m, n_robots=n, loss_p=p, seed=0)
            for m in ("hierarchical", "decentralized", "ic3net", "pibt") for n in ns]


def frames(seeds: int = 2, episodes: int = 120, eval_eps: int = 20, hold: bool = True,
           seed: int = 0, specs: list[dict] | None = None,
           ) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """(cells, train, eval) frames in the store schema (every cell done)."""
    rng = np.random.default_rng(seed)
    cells, train, evals = [], [], []
    for k, spec in enumerate(specs if specs is not None else cell_specs(seeds)):
        cid = f"{k:012x}"
        m, n = spec["method"], spec["n_robots"]
        filt = m == "hierarchical"
        cells.append({
            "cell_id": cid, "grid": "synthetic", **spec, "groups": Z, "ref_size": 8, "search_radius": 2,
            "c_max": 500, "safety_filter": filt, "layout": "wh20", "episodes": episodes, "horizon": 50,
            "eval_episodes": eval_eps, "on_goal": "remove", "loss_model": "bernoulli", "params_json": "{}",
            "config_json": json.dumps(spec), "status": "done", "error": "", "train_episodes_done": episodes,
            "wall_s": 1.0, "peak_mem_mb": 100.0, "attempts": 1, "versions_json": "{}", "schema_version": SCHEMA_VERSION,
            "executions": "planner" if m == "pibt" else "argmax",
        })
        curve = _train_curve(m, n, episodes, rng, hold)
        payload = {"hierarchical": n * (Z - 1) * D_M, "decentralized": n * (n - 1) * D_M}.get(m, n * 16.0)
        if not hold and m == "hierarchical":
            payload *= 1.5
        for e in range(episodes if m != "pibt" else 0):
            train.append({"cell_id": cid, "episode": e, "team_return": curve[e], "success_rate": 0.5,
                          "steps": 50, "payload_scalars_per_step": payload,
                          "payload_dec_per_step": n * (n - 1) * D_M, "wall_s": 0.01})
        good = (m == "hierarchical") == hold
        succ = np.clip(rng.beta(9, 2, eval_eps) if good else rng.beta(2, 5, eval_eps), 0, 1)
        for e in range(eval_eps):
            row = {"cell_id": cid, "episode": e, "execution": "planner" if m == "pibt" else "argmax",
                   "scenario": f"{e:016x}", "team_return": 10 * succ[e], "success_rate": succ[e],
                   "collision_rate": 0.0 if hold else 0.01, "invalid_rate": 0.0,
                   "correction_rate": np.nan, "payload_scalars_per_step": payload,
                   "payload_dec_per_step": n * (n - 1) * D_M, "steps": 50}
            if filt:
                row.update(correction_rate=(0.03 if hold else 0.12) + 0.005 * rng.random(),
                           mean_candidates=_candidates(n, hold) * (1 + 0.01 * rng.random()),
                           fallback_rate=0.0 if hold else 0.5,
                           predictor_error=0.5 + rng.random())
            evals.append(row)
    return pd.DataFrame(cells), pd.DataFrame(train), pd.DataFrame(evals)


def _candidates(n: int, hold: bool) -> float:
    """Mean candidates: Table I's value (3 + N / 10 where it has none), or far above it
    and falling with N."""
    return {40: 3.79, 60: 16.44, 80: 24.15, 90: 35.63, 100: 24.68}.get(n, 3.0 + n / 10) if hold else 500.0 - 3 * n


def joined(cells: pd.DataFrame, rows: pd.DataFrame) -> pd.DataFrame:
    """Rows with their cell's config columns, as reports.data.store gives them."""
    cfg = cells[["cell_id", "method", "n_robots", "loss_p", "seed", "groups", "safety_filter"]]
    return rows.merge(cfg, on="cell_id")


def write_store(run: Path, cells: pd.DataFrame, train: pd.DataFrame, evals: pd.DataFrame,
                manifest: dict | None = None) -> Path:
    """Write the frames as a store under ``run`` with the bench's own writer (bench/store/run_store.py):
    training rows in two parts per cell, one evaluation file per cell."""
    rs = RunStore(run)
    rs.write_cells(cells.to_dict("records"))
    for cid, g in train.groupby("cell_id"):
        half = len(g) // 2
        for part in (g.iloc[:half], g.iloc[half:]):
            if len(part):
                rs.write_train_part(str(cid), int(part["episode"].iloc[0]), part.to_dict("records"))
    for cid, g in evals.groupby("cell_id"):
        rs.write_eval(str(cid), g.to_dict("records"), {"wall_s": 1.0})
    rs.write_manifest(manifest if manifest is not None else {
        "schema_version": SCHEMA_VERSION, "package_version": "0.1.0", "git_sha": "deadbeef", "grid": "synthetic",
        "command": "bench run --grid synthetic", "versions": {"python": "3.12", "torch": "2.13"}})
    return run
