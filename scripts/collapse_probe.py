"""Train one learned cell for a few updates and print its per-update diagnostics.

A small, quick probe of training dynamics: the method, N, p, seed and method parameters of
a cell (the paper's map, horizon and batch unless given), trained for ``--updates`` updates
in this process; per update it prints the mean team return, collision and success rates of
the update's episodes and the ``diag_*`` diagnostics, and with ``--csv`` writes every train
row. Used for the collapse finding (docs/findings/2026-12-06-team-advantage-collapse.md):

    OMP_NUM_THREADS=1 .venv/bin/python scripts/collapse_probe.py decentralized --n 80 --p 0.2 \\
        --seed 2 --updates 15 --csv /tmp/probe.csv
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np
import torch

from algorithms.registry import method_class
from envs.config import EnvConfig

SHOWN = ("team_return", "collision_rate", "success_rate", "critic_loss", "diag_entropy", "diag_entropy_ref",
         "diag_kl", "diag_grad_norm", "diag_adv_mean", "diag_adv_std", "diag_return_mean",
         "diag_explained_variance", "diag_wait_share", "wall_s")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("method")
    ap.add_argument("--n", type=int, default=80)
    ap.add_argument("--p", type=float, default=0.2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--horizon", type=int, default=500)
    ap.add_argument("--updates", type=int, default=15)
    ap.add_argument("--layout", default="warehouse-10-20-10-2-1")
    ap.add_argument("--params", default="{}", help="method parameters as JSON")
    ap.add_argument("--csv", type=Path)
    ap.add_argument("--eval", type=int, default=0, help="then evaluate this many episodes per mode (argmax, sample)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    env = EnvConfig.make(n_robots=args.n, layout=args.layout, horizon=args.horizon, loss_p=args.p, groups=4)
    params = {**json.loads(args.params), **({"eval_chunk": args.eval} if args.eval else {})}
    method = method_class(args.method)(env, params, seed=args.seed)
    rows: list[dict] = []
    print("update", *SHOWN, sep="\t")
    for u in range(args.updates):
        batch = method.train_iteration()
        rows += batch
        means = [float(np.nanmean([float(r.get(k, np.nan)) for r in batch])) for k in SHOWN]
        print(u, *(f"{v:.4g}" for v in means), sep="\t", flush=True)
    for mode in ("argmax", "sample") if args.eval else ():
        ev = method.evaluate(0, execution=mode)
        print(f"eval {mode}: success {np.mean([r['success_rate'] for r in ev]):.3f} "
              f"return {np.mean([r['team_return'] for r in ev]):.1f} over {len(ev)} episodes", flush=True)
    if args.csv:
        keys = sorted({k for r in rows for k in r})
        with args.csv.open("w", newline="") as fh:
            w = csv.DictWriter(fh, keys)
            w.writeheader()
            w.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
