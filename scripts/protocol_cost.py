"""Training cost of protocol = "mappo" against "paper" (at most 1.3x per env-step).

Both protocols of one method on the same configuration in one process, alternating update
by update so machine load hits both alike; prints rollout and update seconds and the ratio
of the totals (decision 0201):

    OMP_NUM_THREADS=1 .venv/bin/python scripts/protocol_cost.py decentralized --n 40
"""
from __future__ import annotations

import argparse
import sys
import time

import torch

from algorithms.common.execution import ActionChoice
from algorithms.registry import method_class
from envs.config import EnvConfig


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("method")
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--horizon", type=int, default=200)
    ap.add_argument("--updates", type=int, default=3)
    args = ap.parse_args()
    torch.set_num_threads(1)
    env = EnvConfig.make(n_robots=args.n, layout="warehouse-10-20-10-2-1", horizon=args.horizon, loss_p=0.2, groups=4)
    methods = {pr: method_class(args.method)(env, {"batch_episodes": 4, "protocol": pr}, seed=0)
               for pr in ("paper", "mappo")}
    seconds = {pr: [0.0, 0.0] for pr in methods}
    for _ in range(args.updates):
        for pr, m in methods.items():
            t0 = time.perf_counter()
            with torch.inference_mode():
                state, _ = m.run(m.train_batch(), ActionChoice.train(m.torch_gen))
            t1 = time.perf_counter()
            m.update(state)
            m.iterations += 1
            seconds[pr][0] += t1 - t0
            seconds[pr][1] += time.perf_counter() - t1
    for pr, (roll, upd) in seconds.items():
        print(f"{pr}: rollout {roll:.2f} s, update {upd:.2f} s")
    print(f"ratio mappo / paper: {sum(seconds['mappo']) / sum(seconds['paper']):.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
