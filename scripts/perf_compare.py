"""Training throughput of two checkouts measured in one run, cell by cell, alternating.

Each measurement is a fresh Python process whose code comes from one checkout (the
timing loop below is the same text for both, so both are measured by the same script):
it builds the method, runs ``--warmup`` training iterations, then times ``--iterations``
full ``Method.train_iteration()`` calls (scenario sampling and environment reset,
rollout, update: what a bench cell pays per update). Before timing, every goal's distance
field is computed in both checkouts (the steady state of a cell: the old per-goal cache
fills within its first few dozen updates), unless ``--cold-fields``. Rates are env-steps (episode-steps)
per second of wall time and of process CPU time (less sensitive to other load on a
shared box). Rounds alternate the order of the two checkouts; the table gives medians.

    .venv/bin/python scripts/perf_compare.py --base /work/wt-perf-base --new . \\
        --methods hierarchical decentralized ic3net --sizes 40 100 --rounds 3
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

SNIPPET = r"""
import json, sys, time
sys.path.insert(0, sys.argv[1])
import torch
torch.set_num_threads(1)
from algorithms.registry import method_class
from envs.config import EnvConfig
method, n, layout = sys.argv[2], int(sys.argv[3]), sys.argv[4]
warmup, iterations, horizon, batch, warm_fields = (int(v) for v in sys.argv[5:10])
extra = json.loads(sys.argv[10])
env = EnvConfig.make(n_robots=n, layout=layout, horizon=horizon, loss_p=0.2, groups=min(4, n))
m = method_class(method)(env, {"batch_episodes": batch, **extra}, seed=0)
if warm_fields:  # steady state: every goal's distance field already known (both checkouts)
    import numpy as np
    from envs.distances import distance_cache
    distance_cache(m.layout).fields(np.arange(m.layout.n_free))
for _ in range(warmup):
    m.train_iteration()
steps = 0
w0, c0 = time.perf_counter(), time.process_time()
for _ in range(iterations):
    steps += int(sum(r["steps"] for r in m.train_iteration()))
wall, cpu = time.perf_counter() - w0, time.process_time() - c0
print(json.dumps({"steps": steps, "wall_s": wall, "cpu_s": cpu}))
"""


def measure(tree: Path, method: str, n: int, layout: str, args: argparse.Namespace) -> dict:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "PYTHONPATH": str(tree)}
    cmd = [sys.executable, "-c", SNIPPET, str(tree), method, str(n), layout, str(args.warmup),
           str(args.iterations), str(args.horizon), str(args.batch), str(int(not args.cold_fields)), args.params]
    out = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", type=Path, required=True)
    ap.add_argument("--new", type=Path, required=True)
    ap.add_argument("--methods", nargs="+", default=["hierarchical", "decentralized", "ic3net"])
    ap.add_argument("--sizes", nargs="+", type=int, default=[40, 100])
    ap.add_argument("--layout", default="warehouse-10-20-10-2-1")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--iterations", type=int, default=3)
    ap.add_argument("--horizon", type=int, default=200)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--cold-fields", action="store_true",
                    help="do not precompute every goal's distance field first (default: steady state, "
                         "as after the first few dozen updates of a cell)")
    ap.add_argument("--params", default="{}",
                    help='method parameters for both checkouts (JSON), e.g. \'{"hidden": 64}\' to compare '
                         'the same network when the defaults differ between them')
    ap.add_argument("--json", type=Path, default=None, help="also write every measurement here")
    args = ap.parse_args()
    trees = {"base": args.base.resolve(), "new": args.new.resolve()}
    records = []
    for method in args.methods:
        for n in args.sizes:
            for r in range(args.rounds):
                order = ["base", "new"] if r % 2 == 0 else ["new", "base"]
                for name in order:
                    res = measure(trees[name], method, n, args.layout, args)
                    records.append({"method": method, "n": n, "round": r, "tree": name, **res})
                    print(f"{method:13s} N={n:3d} round {r} {name:4s} "
                          f"{res['steps'] / res['wall_s']:8.0f} env-steps/s wall, "
                          f"{res['steps'] / res['cpu_s']:8.0f} cpu", flush=True)
    if args.json:
        args.json.write_text(json.dumps(records, indent=1))
    print("\nmethod         N   base wall  new wall  ratio | base cpu   new cpu  ratio")
    for method in args.methods:
        for n in args.sizes:
            rate = {}
            for name in trees:
                rows = [x for x in records if x["method"] == method and x["n"] == n and x["tree"] == name]
                rate[name] = (statistics.median(x["steps"] / x["wall_s"] for x in rows),
                              statistics.median(x["steps"] / x["cpu_s"] for x in rows))
            (bw, bc), (nw, nc) = rate["base"], rate["new"]
            print(f"{method:13s} {n:3d} {bw:10.0f} {nw:9.0f} {nw / bw:6.2f} | {bc:8.0f} {nc:9.0f} {nc / bc:6.2f}")


if __name__ == "__main__":
    main()
