"""What a second torch thread gives one cell: wall and CPU time of one training update at 1
and at 2 intra-op threads (``bench run --cell-threads``), rollout and update apart.

Each method is built once (N robots on the MovingAI warehouse map), warmed up by one update,
and its state kept; every timed update starts from that state (the same arithmetic each
time), the thread counts alternating round by round (1, 2, then 2, 1, ...) so a load that
drifts falls on both alike. Prints one line per timed update and the medians per thread
count, with the load average (``os.getloadavg``) before and after: on a busy box wall times
say little (a second thread competes with the load) while CPU times (``time.process_time``,
all threads of the process) say what the second thread costs:

    nice .venv/bin/python scripts/thread_gain.py --rounds 3 --horizon 200
"""
from __future__ import annotations

import argparse
import copy
import os
import statistics
import sys
import time

import torch

from algorithms.registry import method_class
from bench.perf.methods import REAL_MAP
from bench.perf.timing import time_training
from envs.config import EnvConfig


def timed_update(method, state, threads: int) -> dict[str, float]:
    """One update of ``method`` from ``state`` on ``threads`` torch threads: wall and CPU s."""
    torch.set_num_threads(threads)
    method.load_state_dict(copy.deepcopy(state))
    cpu0, main0, wall0 = time.process_time(), time.thread_time(), time.perf_counter()
    t = time_training(method, 1)
    return {"wall_s": time.perf_counter() - wall0, "cpu_s": time.process_time() - cpu0,
            "main_cpu_s": time.thread_time() - main0,
            "rollout_s": t["rollout_s"], "update_s": t["update_s"]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--methods", default="hierarchical,decentralized")
    ap.add_argument("--n-robots", type=int, default=100)
    ap.add_argument("--horizon", type=int, default=200)
    ap.add_argument("--batch-episodes", type=int, default=8)
    ap.add_argument("--rounds", type=int, default=3, help="timed updates per thread count")
    args = ap.parse_args()
    print(f"load average before: {os.getloadavg()}  cpus: {os.cpu_count()}", flush=True)
    for name in args.methods.split(","):
        torch.set_num_threads(1)
        env = EnvConfig.make(n_robots=args.n_robots, layout=str(REAL_MAP), horizon=args.horizon,
                             loss_p=0.2, groups=min(4, args.n_robots))
        m = method_class(name)(env, {"batch_episodes": args.batch_episodes}, seed=0)
        time_training(m, 1)  # warm-up: kernels, the layout's distance table
        state = copy.deepcopy(m.state_dict())
        got: dict[int, list[dict[str, float]]] = {1: [], 2: []}
        for r in range(args.rounds):
            for threads in ((1, 2) if r % 2 == 0 else (2, 1)):
                res = timed_update(m, state, threads)
                got[threads].append(res)
                print(f"{name} round {r} threads {threads}: " + " ".join(f"{k} {v:.2f}" for k, v in res.items())
                      + f"  load {os.getloadavg()[0]:.2f}", flush=True)
        for threads, rs in got.items():
            med = {k: statistics.median(x[k] for x in rs) for k in rs[0]}
            print(f"{name} median threads {threads}: " + " ".join(f"{k} {v:.2f}" for k, v in med.items()))
        base = {k: statistics.median(x[k] for x in got[1]) for k in got[1][0]}
        two = {k: statistics.median(x[k] for x in got[2]) for k in got[2][0]}
        print(f"{name} 1->2 threads: wall x{base['wall_s'] / two['wall_s']:.2f} faster, "
              f"CPU x{two['cpu_s'] / base['cpu_s']:.2f}, update x{base['update_s'] / two['update_s']:.2f} faster, "
              f"rollout x{base['rollout_s'] / two['rollout_s']:.2f} faster", flush=True)
    print(f"load average after: {os.getloadavg()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
