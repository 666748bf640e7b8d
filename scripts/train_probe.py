"""Short training probe: one learned method on the MovingAI map, K updates, one seed.

Prints one JSON line every ``--every`` updates (mean training success and team return
over that window) and a final line (optionally with an evaluation in each ``--execution``
mode, on the same scenarios). Used for the shared-defaults measurement and the
IC3Net N = 40 before/after numbers in docs/findings/ (IC3Net at N = 40), e.g.

    nice -n 10 python scripts/train_probe.py --method ic3net --n 30 --horizon 200 \\
        --updates 40 --seed 0 --eval-chunks 0 --params '{"lr": 0.003}'
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

from algorithms.registry import method_class
from envs.config import EnvConfig

MAP = "envs/maps/warehouse-10-20-10-2-1.map"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", required=True)
    ap.add_argument("--n", type=int, required=True, help="team size N")
    ap.add_argument("--p", type=float, default=0.2, help="message loss p")
    ap.add_argument("--horizon", type=int, default=200)
    ap.add_argument("--updates", type=int, required=True, help="training updates (8 episodes each)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--params", default="{}", help="method parameter overrides (JSON)")
    ap.add_argument("--eval-chunks", type=int, default=2, help="evaluation chunks of 10 episodes at the end")
    ap.add_argument("--execution", nargs="+", default=["argmax"],
                    help="evaluation modes (argmax, sample, sample@T), each on the same chunks")
    ap.add_argument("--every", type=int, default=10)
    ap.add_argument("--tag", default="")
    a = ap.parse_args()
    torch.set_num_threads(1)
    env = EnvConfig(n_robots=a.n, layout=MAP, horizon=a.horizon, loss_p=a.p)
    m = method_class(a.method)(env, json.loads(a.params), seed=a.seed)
    t0, succ, rets = time.time(), [], []
    for k in range(a.updates):
        rows = m.train_iteration()
        succ.append(float(np.mean([r["success_rate"] for r in rows])))
        rets.append(float(np.mean([r["team_return"] for r in rows])))
        if (k + 1) % a.every == 0:
            print(json.dumps({"tag": a.tag, "update": k + 1, "train_success": float(np.mean(succ[-a.every:])),
                              "ret_window": float(np.mean(rets[-a.every:])),
                              "wall": round(time.time() - t0)}), flush=True)
    final = {"tag": a.tag, "final": True, "updates": a.updates,
             "last10_train_success": float(np.mean(succ[-10:])), "last10_return": float(np.mean(rets[-10:]))}
    for mode in a.execution if a.eval_chunks else ():
        ev = [r for c in range(a.eval_chunks) for r in m.evaluate(c, execution=mode)]
        final.update({f"{key}[{mode}]": float(np.mean([r[col] for r in ev])) for key, col in (
            ("eval_success", "success_rate"), ("eval_return", "team_return"),
            ("eval_collision", "collision_rate"))})
    final["wall"] = round(time.time() - t0)
    print(json.dumps(final), flush=True)


if __name__ == "__main__":
    main()
