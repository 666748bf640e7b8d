"""Train the hierarchical method briefly and probe its reference layer (issue 18 item 2).

Usage: python scripts/reference_study.py NAME '{"ref_hold": 8}' [--n 20] [--iters 100]
Writes one JSON line per probe to results/reference_study/NAME.jsonl (training entropy of
mu per update, and ``probe_reference`` every --probe-every updates and at the end).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from algorithms.hierarchical.method import HierarchicalMethod
from algorithms.hierarchical.reference_probe import probe_reference
from envs.config import EnvConfig
from envs.layouts import PAPER_MAP


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("name")
    ap.add_argument("params", nargs="?", default="{}")
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--p", type=float, default=0.2)
    ap.add_argument("--horizon", type=int, default=200)
    ap.add_argument("--iters", type=int, default=100)
    ap.add_argument("--probe-every", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    torch.set_num_threads(1)
    env = EnvConfig.make(n_robots=a.n, layout=PAPER_MAP, horizon=a.horizon, loss_p=a.p)
    m = HierarchicalMethod(env, json.loads(a.params), seed=a.seed)
    out = Path("results/reference_study") / f"{a.name}.jsonl"
    out.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    with out.open("w") as f:
        for it in range(a.iters):
            rows = m.train_iteration()
            rec = {"iter": it + 1, "episodes": m.episodes_done,
                   "entropy_ref": rows[0]["entropy_ref"], "entropy_local": rows[0]["entropy_local"],
                   "train_success": float(np.mean([r["success_rate"] for r in rows])),
                   "team_return": float(np.mean([r["team_return"] for r in rows])),
                   "wall": time.time() - t0}
            if (it + 1) % a.probe_every == 0 or it + 1 == a.iters:
                rec.update(probe_reference(m, batches=2, batch_size=5, seed=1000))
            f.write(json.dumps(rec) + "\n")
            f.flush()


if __name__ == "__main__":
    main()
