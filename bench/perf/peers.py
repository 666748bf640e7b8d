"""``bench perf --suite peers``: our trainer against the trainer a user would pick instead.

In one run, on the same environment (``warehouse_v0`` on the MovingAI map
warehouse-10-20-10-2-1, p = 0.2, horizon 200), the same networks (2 hidden layers of 64,
parameters shared across robots) and the same batch (1,600 env-steps), on one torch thread:

* ``torchrl-mappo``: TorchRL's MAPPO through ``PettingZooWrapper`` exactly as the README's
  interop recipe builds it (``tests/interop/recipe_torchrl.py``: ``MultiAgentMLP`` actor
  and centralised critic, ``ClipPPOLoss`` with GAE), ``frames_per_batch`` = 1,600,
  4 PPO epochs; timed from the collector's start to the last optimizer step of one batch;
* ``ours-decentralized``: our decentralized baseline's ``train_iteration()`` (8 episodes x
  200 steps, rollout and update) after one warm-up update (bench/perf/methods.py).

Rates are env-steps (one step of the whole team) per second of wall time and of process CPU
time (``_cpu``: what one dedicated core would give on a shared, busy machine); ``ratio`` is
ours over TorchRL's at the same N. Other peers do not install here: BenchMARL 1.5 requires
``torchrl~=0.10`` (we pin 0.14.1), which resolves to torch 2.14 with CUDA wheels, and EPyMARL
is not on PyPI; the suite says so in ``note`` rather than leaving them out silently.
"""
from __future__ import annotations

import importlib.util
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import pandas as pd
import torch

from bench.perf.methods import REAL_MAP, measure_cell_training
from envs.errors import BenchError

RECIPE = Path(__file__).resolve().parents[2] / "tests" / "interop" / "recipe_torchrl.py"
PEER_SIZES = (40, 100)
FRAMES = 1600  # = 8 episodes x horizon 200: our batch
EPOCHS = 4
HORIZON = 200
LOSS_P = 0.2


def load_recipe() -> ModuleType:
    """The README's TorchRL recipe module (a checkout and the dev extra: torchrl)."""
    if not RECIPE.is_file():
        raise BenchError(f"perf suite 'peers' needs the repository checkout ({RECIPE} not found)")
    try:
        import torchrl  # noqa: F401
    except ImportError as exc:
        raise BenchError(f"perf suite 'peers' needs torchrl (the dev extra): {exc}") from None
    spec = importlib.util.spec_from_file_location("recipe_torchrl", RECIPE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def measure_torchrl(n_robots: int, frames: int = FRAMES, epochs: int = EPOCHS, horizon: int = HORIZON,
                    layout: str | None = None, loss_p: float = LOSS_P, seed: int = 0) -> dict[str, Any]:
    """Env-steps/s of one TorchRL MAPPO batch of ``frames`` env-steps and ``epochs`` epochs."""
    torch.set_num_threads(1)
    recipe = load_recipe()
    where = layout or str(REAL_MAP)
    env = recipe.make_env(seed, n_robots=n_robots, layout=where, loss_p=loss_p, horizon=horizon)
    torch.manual_seed(seed)
    actor, critic = recipe.make_agents(env)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    recipe.train(env, actor, critic, frames=frames, batch=frames, epochs=epochs)
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    env.close()
    return {"peer": "torchrl-mappo", "n_robots": n_robots, "layout": Path(where).stem, "horizon": horizon,
            "env_steps": frames, "env_steps_per_s": frames / wall, "env_steps_per_s_cpu": frames / cpu,
            "wall_s": wall}


def measure_ours(n_robots: int, horizon: int = HORIZON, layout: str | None = None,
                 batch_episodes: int | None = None, iterations: int = 1) -> dict[str, Any]:
    """Env-steps/s of our decentralized trainer's updates on the same batch."""
    where = layout or str(REAL_MAP)
    batch = batch_episodes or max(1, FRAMES // horizon)
    t0 = time.perf_counter()
    r = measure_cell_training("decentralized", n_robots, where, iterations=iterations, warmup=1,
                              batch_episodes=batch, horizon=horizon, loss_p=LOSS_P)
    return {"peer": "ours-decentralized", "n_robots": n_robots, "layout": r["layout"], "horizon": horizon,
            "env_steps": r["episode_steps"], "env_steps_per_s": r["env_steps_per_s"],
            "env_steps_per_s_cpu": r["env_steps_per_s_cpu"], "wall_s": time.perf_counter() - t0}


def run_peers_suite(sizes: tuple[int, ...] = PEER_SIZES, frames: int = FRAMES, horizon: int = HORIZON,
                    layout: str | None = None) -> pd.DataFrame:
    """One row per (peer, N) and the ratio ours / TorchRL at each N."""
    rows = []
    for n in sizes:
        peer = measure_torchrl(n, frames=frames, horizon=horizon, layout=layout)
        ours = measure_ours(n, horizon=horizon, layout=layout, batch_episodes=max(1, frames // horizon))
        ratio = ours["env_steps_per_s"] / peer["env_steps_per_s"]
        ratio_cpu = ours["env_steps_per_s_cpu"] / peer["env_steps_per_s_cpu"]
        for r in (peer, ours):
            rows.append({"suite": "peers", **r, "ratio_ours_over_torchrl": ratio,
                         "ratio_ours_over_torchrl_cpu": ratio_cpu,
                         "note": "" if r is ours else f"{frames} frames/batch, {EPOCHS} PPO epochs, 2x64 shared"})
    rows.append({"suite": "peers", "peer": "benchmarl/epymarl", "note": "not measured: BenchMARL 1.5 needs "
                 "torchrl~=0.10 (ours 0.14), which pulls torch 2.14 with CUDA; EPyMARL is not on PyPI"})
    return pd.DataFrame(rows)
