"""Train the hierarchical method briefly and probe its reference layer (issue 18 item 2).

Usage: python maintenance/reference_study.py NAME '{"ref_hold": 8}' [--n 20] [--iters 100]
Writes one JSON line per probe to results/reference_study/NAME.jsonl (training entropy of
mu per update, and ``probe_reference`` every --probe-every updates and at the end).
"""
from __future__ import annotations

import argparse
import copy
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
from reference_probe import probe_reference  # noqa: E402  (scripts/reference_probe.py, a live probe library)

from algorithms.common.episodes import EpisodeBatch, batch_rng
from algorithms.common.execution import ActionChoice
from algorithms.hierarchical.method import HierarchicalMethod
from algorithms.hierarchical.training import policy_update
from envs.config import EnvConfig
from paper.settings import PAPER_MAP


def gradient_agreement(m: HierarchicalMethod, seed: int, pairs: int = 2) -> dict[str, float]:
    """Is there a signal in the policy gradient of mu? Cosine between the gradients of two
    independent training batches at the same parameters (entropy bonus off), for mu and for
    pi: about 0 means noise, clearly > 0 a direction the data agree on. Also the ratio of
    mu's gradient norm to pi's."""
    def grads(k: int) -> tuple[torch.Tensor, torch.Tensor]:
        c = copy.deepcopy(m)
        c.params = c.params.model_copy(update={"entropy_coef": 0.0, "ref_entropy_coef": 0.0})
        c.torch_gen = torch.Generator().manual_seed(seed * 1000 + k)  # independent samples of r and U
        batch = EpisodeBatch(c.env, c.params.batch_episodes, batch_rng(seed, 2, k), c.layout)
        with torch.no_grad():
            state, _ = c.run(batch, ActionChoice.train(c.torch_gen))
        policy_update(c.learner(), state.buffer)
        def flat(mod: torch.nn.Module) -> torch.Tensor:
            return torch.cat([q.grad.reshape(-1) for q in mod.parameters() if q.grad is not None])
        return flat(c.reference), flat(c.local)
    out: dict[str, list[float]] = {"cos_mu": [], "cos_pi": [], "norm_mu_over_pi": []}
    for j in range(pairs):
        (a_mu, a_pi), (b_mu, b_pi) = grads(2 * j), grads(2 * j + 1)
        out["cos_mu"].append(float(torch.nn.functional.cosine_similarity(a_mu, b_mu, dim=0)))
        out["cos_pi"].append(float(torch.nn.functional.cosine_similarity(a_pi, b_pi, dim=0)))
        out["norm_mu_over_pi"].append(float(a_mu.norm() / a_pi.norm().clamp_min(1e-12)))
    return {k: float(np.mean(v)) for k, v in out.items()}


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
                rec.update(gradient_agreement(m, seed=2000 + it))
            f.write(json.dumps(rec) + "\n")
            f.flush()
    torch.save(m.state_dict(), out.with_suffix(".pt"))  # for further probes


if __name__ == "__main__":
    main()
