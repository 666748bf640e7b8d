"""Peer check of the mappo protocol: TorchRL's MAPPO (the interop recipe,
tests/interop/recipe_torchrl.py) and ours at the same number of environment steps on one
small configuration; prints the share of robots that reach their goal with sampled actions.

    OMP_NUM_THREADS=1 .venv/bin/python scripts/peer_check.py --steps 6000
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from algorithms.registry import method_class  # noqa: E402
from envs.config import EnvConfig  # noqa: E402

CONFIG = dict(n_robots=8, layout="tiny", horizon=40)


def ours(protocol: str, steps: int, seed: int, episodes: int) -> float:
    env = EnvConfig.make(loss_p=0.2, groups=2, **CONFIG)
    m = method_class("decentralized")(env, {"batch_episodes": 8, "eval_chunk": episodes, "protocol": protocol},
                                      seed=seed)
    done = 0
    while done < steps:
        done += sum(int(r["steps"]) for r in m.train_iteration())
    return float(np.mean([r["success_rate"] for r in m.evaluate(0, execution="sample")]))


def torchrl(steps: int, seed: int, episodes: int) -> float:
    from tests.interop.recipe_torchrl import arrived, make_agents, make_env, train

    torch.manual_seed(seed)
    env = make_env(seed, **CONFIG)
    actor, critic = make_agents(env)
    train(env, actor, critic, frames=steps)
    return arrived(env, actor, episodes=episodes)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=6000)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--episodes", type=int, default=20)
    args = ap.parse_args()
    torch.set_num_threads(1)
    for seed in range(args.seeds):
        row = {"ours mappo": ours("mappo", args.steps, seed, args.episodes),
               "ours paper": ours("paper", args.steps, seed, args.episodes),
               "torchrl mappo": torchrl(args.steps, seed, args.episodes)}
        print(f"seed {seed}: " + ", ".join(f"{k} {v:.3f}" for k, v in row.items()), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
