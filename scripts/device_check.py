"""Does an accelerator pay? Train each learned method on the device and on the CPU, same call.

For hierarchical, decentralized and ic3net (paper protocol, default parameters), builds the
same cell twice, its networks on ``--device`` and on the CPU (``Method(..., device=)``,
algorithms/common/device.py), runs ``--warmup`` training iterations untimed and then
``--iterations`` timed ones, and prints per method the environment steps per second (one
step of one episode; x N for robot-steps) of each and their ratio. The environment,
observations, safety filter and sampling run on the host in both (docs/guide/speed.md,
"Accelerators"), so the ratio is what the device path gives today, not what a full device
path would. Also printed: the mean team return of the timed episodes on each (the same
scenarios; the numbers differ only by float rounding, so they should be close, not equal).

    .venv/bin/python scripts/device_check.py                     # on a CUDA machine (< 10 min)
    .venv/bin/python scripts/device_check.py --device cpu --n-robots 6 --layout tiny \\
        --horizon 16 --batch-episodes 2 --iterations 1 --warmup 0     # the script itself, here

Without the device (no CUDA, a CPU build of torch) it prints one line and exits 2. The CPU
side uses ``--cpu-threads`` torch threads (1: a bench worker's setting). ``--budget-s``
stops starting new measurements once that much time has passed (the rest is reported as
skipped), so a slow machine still finishes. ``--out FILE`` writes the results as JSON.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import torch

from algorithms.common.device import resolve_device
from algorithms.registry import method_class
from envs.config import EnvConfig
from envs.errors import BenchError

METHODS = ("hierarchical", "decentralized", "ic3net")


def measure(method: str, env: EnvConfig, batch: int, device: torch.device, warmup: int, iterations: int,
            seed: int) -> dict[str, Any]:
    """Env-steps/s of ``iterations`` timed training iterations of one cell on ``device``."""
    m = method_class(method)(env, {"batch_episodes": batch}, seed=seed, device=device)
    for _ in range(warmup):
        m.train_iteration()
    if device.type == "cuda":
        torch.cuda.synchronize(device)
    t0 = time.perf_counter()
    rows = [r for _ in range(iterations) for r in m.train_iteration()]
    if device.type == "cuda":
        torch.cuda.synchronize(device)
    wall = time.perf_counter() - t0
    steps = sum(int(r["steps"]) for r in rows)
    return {"device": str(device), "iterations": iterations, "episodes": len(rows), "env_steps": steps,
            "wall_s": wall, "env_steps_per_s": steps / wall if wall > 0 else float("nan"),
            "robot_steps_per_s": steps * env.n_robots / wall if wall > 0 else float("nan"),
            "team_return": sum(float(r["team_return"]) for r in rows) / max(len(rows), 1)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", default="cuda", help="the accelerator (default cuda); cpu checks the script")
    ap.add_argument("--methods", default=",".join(METHODS), help="comma-separated learned methods")
    ap.add_argument("--n-robots", type=int, default=100)
    ap.add_argument("--layout", default=None, help="layout (default: the preset sized for N)")
    ap.add_argument("--groups", type=int, default=None, help="groups Z (default: the environment's)")
    ap.add_argument("--horizon", type=int, default=200)
    ap.add_argument("--loss-p", type=float, default=0.3)
    ap.add_argument("--batch-episodes", type=int, default=8)
    ap.add_argument("--warmup", type=int, default=1, help="untimed iterations first (allocator, kernels)")
    ap.add_argument("--iterations", type=int, default=2, help="timed training iterations per method and device")
    ap.add_argument("--cpu-threads", type=int, default=1, help="torch threads of the CPU side")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--budget-s", type=float, default=480.0, help="start no measurement after this many seconds")
    ap.add_argument("--out", type=Path, default=None, help="write the results here (JSON)")
    args = ap.parse_args(argv)
    try:
        device = resolve_device(args.device, "--device")
        methods = [m.strip() for m in args.methods.split(",") if m.strip()]
        for name in methods:
            if not method_class(name).learned:
                raise BenchError(f"device_check --methods: {name} is not a learned method")
        extra = {k: v for k, v in (("layout", args.layout), ("groups", args.groups)) if v is not None}
        env = EnvConfig.make(n_robots=args.n_robots, horizon=args.horizon, loss_p=args.loss_p, **extra)
    except BenchError as exc:
        print(f"device_check: {exc}", file=sys.stderr)
        return 2
    torch.set_num_threads(args.cpu_threads)
    cpu = torch.device("cpu")
    name = torch.cuda.get_device_name(device) if device.type == "cuda" else str(device)
    print(f"device {device} ({name}) against the cpu ({args.cpu_threads} torch thread(s)); torch {torch.__version__}; "
          f"N={env.n_robots} layout={env.layout} Z={env.groups} T={env.horizon} p={env.loss_p} "
          f"B={args.batch_episodes}; {args.warmup} warm-up + {args.iterations} timed iterations", flush=True)
    start = time.perf_counter()
    results: dict[str, dict[str, Any]] = {}
    header = f"{'method':<14} {'device env-steps/s':>19} {'cpu env-steps/s':>16} {'ratio':>7} {'return dev/cpu':>17}"
    print(header, flush=True)
    for method in methods:
        res: dict[str, Any] = {}
        for label, dev in (("device", device), ("cpu", cpu)):
            if time.perf_counter() - start > args.budget_s:
                res[label] = None
                continue
            res[label] = measure(method, env, args.batch_episodes, dev, args.warmup, args.iterations, args.seed)
        d, c = res["device"], res["cpu"]
        ratio = d["env_steps_per_s"] / c["env_steps_per_s"] if d and c else float("nan")
        res["ratio"] = ratio
        results[method] = res
        fmt = (lambda r: f"{r['env_steps_per_s']:.1f}" if r else "skipped")  # noqa: E731
        ret = f"{d['team_return']:.3f}/{c['team_return']:.3f}" if d and c else "-"
        print(f"{method:<14} {fmt(d):>19} {fmt(c):>16} {ratio:>7.2f} {ret:>17}", flush=True)
    print(f"total {time.perf_counter() - start:.1f} s (ratio > 1: the device trains faster)")
    if args.out is not None:
        args.out.write_text(json.dumps({"device": str(device), "device_name": name, "torch": torch.__version__,
                                         "args": {k: str(v) for k, v in vars(args).items()},
                                         "results": results}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
