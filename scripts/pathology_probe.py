"""Probe the hierarchical method's two pathologies on one short training run.

    .venv/bin/python scripts/pathology_probe.py NAME '{"ref_hold": 10}' [--n 40] [--iters 60]

Trains one hierarchical arm (N robots, p, the paper's map, horizon 300, updates of 8
episodes), then measures on evaluation scenarios:

* the reference layer (``scripts/reference_probe.py``'s ``probe_reference``): H(mu),
  I(r; o), I(r; u_i | s), the modal argmax r's share, success with argmax r vs uniform r;
* the argmax livelock: argmax (and sample) success with the fallback rule swapped at
  evaluation on the *same* weights -- joint Wait (Alg. 1 line 12, the paper), resample once
  (``resample_on_fallback``), per-robot Wait (``fallback="per_robot"``) and both -- with the
  fallback rate (group-steps that fell back) and correction rate beside each success;
* with ``--eval-n M``, the same fallback table for the trained weights evaluated with M
  robots (the architecture handles any group size; a transfer, labelled as such).

``--checkpoint PATH`` probes a bench checkpoint of the method instead of training one (e.g.
a cell of a committed run): its cell gives N, p, the horizon, the map and the parameters,
and ``params``, ``--n``, ``--p``, ``--horizon``, ``--iters`` and ``--seed`` are not used.

One JSON line per arm to results/pathology_probe/NAME.json. One thread; minutes per arm.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from reference_probe import probe_reference  # scripts/reference_probe.py

from algorithms.hierarchical.method import HierarchicalMethod
from bench.design.cells import Cell
from bench.store.checkpoints import load_checkpoint
from envs.config import EnvConfig

FALLBACKS: dict[str, dict[str, Any]] = {
    "joint": {"fallback": "joint", "resample_on_fallback": False},
    "resample": {"fallback": "joint", "resample_on_fallback": True},
    "per_robot": {"fallback": "per_robot", "resample_on_fallback": False},
    "per_robot+resample": {"fallback": "per_robot", "resample_on_fallback": True},
}
MAP = "warehouse-10-20-10-2-1"  # the bundled MovingAI map that stands in for the paper's layouts
EVAL_SEED = 4242  # evaluation scenarios, outside every training seed used here


def fallback_table(m: HierarchicalMethod, chunks: int) -> dict[str, dict[str, float]]:
    """Success, fallback and correction rates of each fallback rule (and sample mode) on m's weights."""
    base = m.params
    out: dict[str, dict[str, float]] = {}
    for name, update in FALLBACKS.items():
        m.params = base.model_copy(update=update)
        for mode in ("argmax", "sample"):
            if mode == "sample" and name != "joint":
                continue  # sampling rarely falls back; one row for scale
            rows = [r for c in range(chunks) for r in m.evaluate(c, seed=EVAL_SEED, execution=mode)]
            out[f"{mode}/{name}"] = {k: float(np.mean([r[k] for r in rows])) for k in
                                     ("success_rate", "fallback_rate", "correction_rate", "collision_rate")}
    m.params = base
    return out


def _trained(a: argparse.Namespace) -> tuple[HierarchicalMethod, dict[str, Any]]:
    """One arm trained here: a.iters updates at a.n robots, p = a.p, horizon a.horizon."""
    params = {"eval_chunk": 10, **json.loads(a.params)}
    env = EnvConfig.make(n_robots=a.n, layout=MAP, horizon=a.horizon, loss_p=a.p)
    m = HierarchicalMethod(env, params, seed=a.seed)
    t0 = time.time()
    train = [float(np.mean([r["success_rate"] for r in m.train_iteration()])) for _ in range(a.iters)]
    return m, {"name": a.name, "params": params, "n": a.n, "p": a.p, "horizon": a.horizon, "seed": a.seed,
               "episodes": m.episodes_done, "train_wall_s": round(time.time() - t0, 1),
               "train_success_last10": float(np.mean(train[-10:]))}


def _from_checkpoint(name: str, path: str) -> tuple[HierarchicalMethod, dict[str, Any]]:
    """The method of a bench checkpoint, at its cell's configuration, with its weights."""
    ckpt = load_checkpoint(path)
    cell = Cell.make(**json.loads(ckpt["cell"]))
    if cell.method != "hierarchical":
        raise SystemExit(f"pathology_probe: {path}: a {cell.method} checkpoint; the probe is the hierarchical method's")
    params = cell.method_params().model_dump(mode="json")
    m = HierarchicalMethod(cell.to_env_config(), params, seed=cell.seed)
    m.load_state_dict(ckpt["state"])
    return m, {"name": name, "checkpoint": path, "cell_id": cell.cell_id, "params": params, "n": cell.n_robots,
               "p": cell.loss_p, "horizon": cell.horizon, "seed": cell.seed, "episodes": int(ckpt["episodes_done"])}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("name")
    ap.add_argument("params", nargs="?", default="{}")
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--p", type=float, default=0.2)
    ap.add_argument("--horizon", type=int, default=300)
    ap.add_argument("--iters", type=int, default=60)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--chunks", type=int, default=2, help="evaluation chunks of 10 episodes per fallback rule")
    ap.add_argument("--eval-n", type=int, default=0, help="also evaluate the weights with this many robots")
    ap.add_argument("--checkpoint", default="", help="probe this bench checkpoint instead of training")
    a = ap.parse_args()
    torch.set_num_threads(1)
    t0 = time.time()
    if a.checkpoint:
        m, rec = _from_checkpoint(a.name, a.checkpoint)
    else:
        m, rec = _trained(a)
    env = m.env
    rec["reference"] = probe_reference(m, batches=2, batch_size=5, seed=1000)
    rec["fallback"] = fallback_table(m, a.chunks)
    if a.eval_n:
        big = HierarchicalMethod(EnvConfig.make(n_robots=a.eval_n, layout=env.layout, horizon=env.horizon,
                                                loss_p=env.loss_p), m.params.model_dump(mode="json"), seed=m.seed)
        big.load_state_dict(m.state_dict())
        rec[f"fallback_n{a.eval_n}"] = fallback_table(big, a.chunks)
    rec["wall_s"] = round(time.time() - t0, 1)
    out = Path("results/pathology_probe") / f"{a.name}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rec, indent=1) + "\n")
    print(json.dumps(rec), flush=True)


if __name__ == "__main__":
    main()
