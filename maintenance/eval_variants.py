"""Evaluate one checkpoint of maintenance/reference_study.py under execution-time variants.

Usage: python maintenance/eval_variants.py results/reference_study/NAME.pt '{"ref_hold": 10}' [--n 20]
The second argument is the training params of the checkpoint; each variant below only
changes how the trained networks are executed (same scenarios and loss draws):
messages predicted / oracle / last, fallback joint / per_robot, resample_on_fallback.
Prints, per variant: success, episodes with a collision, collision rate, corrections,
fallback rate (argmax at both levels, ``--episodes`` evaluation episodes).
"""
from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np
import torch

from algorithms.hierarchical.method import HierarchicalMethod
from envs.config import EnvConfig
from paper.settings import PAPER_MAP

VARIANTS: dict[str, dict[str, Any]] = {
    "paper": {}, "oracle messages": {"messages": "oracle"}, "last-received": {"messages": "last"},
    "per-robot fallback": {"fallback": "per_robot"}, "resample on fallback": {"resample_on_fallback": True},
    "per-robot + resample": {"fallback": "per_robot", "resample_on_fallback": True},
}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("checkpoint")
    ap.add_argument("params", nargs="?", default="{}")
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--p", type=float, default=0.2)
    ap.add_argument("--horizon", type=int, default=300)
    ap.add_argument("--episodes", type=int, default=20)
    a = ap.parse_args()
    torch.set_num_threads(1)
    env = EnvConfig.make(n_robots=a.n, layout=PAPER_MAP, horizon=a.horizon, loss_p=a.p)
    state = torch.load(a.checkpoint, weights_only=True)
    for name, extra in VARIANTS.items():
        m = HierarchicalMethod(env, {**json.loads(a.params), **extra}, seed=0)
        m.load_state_dict(state)
        rows = [r for c in range(a.episodes // m.params.eval_chunk) for r in m.evaluate(c, seed=777)]
        col = np.array([r["collision_rate"] for r in rows])
        print(f"{name:22s} success {np.mean([r['success_rate'] for r in rows]):.3f}  "
              f"episodes with collision {int((col > 0).sum())}/{len(rows)}  collision rate {col.mean():.5f}  "
              f"corrections {np.mean([r['correction_rate'] for r in rows]):.3f}  "
              f"fallback {np.nanmean([r['fallback_rate'] for r in rows]):.3f}", flush=True)


if __name__ == "__main__":
    main()
