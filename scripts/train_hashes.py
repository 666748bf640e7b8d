"""Fingerprints of training and evaluation for every learned method: is a change bit for bit?

For each configuration below (every learned method and the variants whose code paths differ:
shared parameters, the per-robot fallback and resampling, oracle messages with a held
reference, several update chunks, the group advantage, the baselines' safety filter and
per-robot trainer, both layouts and both ``on_goal`` rules; the mappo protocol of each
method), train 3 updates of 4 episodes
of 60 steps at p = 0.3 from seed 3, then evaluate one chunk in argmax, sample and
sample@0.5. Prints, per configuration, 12 hex digits of SHA-256 over the training rows
(without wall times and the ``diag_*`` diagnostics, which only read the update), over the
final parameters of every module, and over the evaluation rows. A speed change that keeps
the arithmetic leaves all three unchanged; a change of float rounding moves the training
rows (their losses) and the parameters, while the evaluation rows (rates and counts) may
stay:

    .venv/bin/python scripts/train_hashes.py --out /tmp/before.json     # on the old code
    .venv/bin/python scripts/train_hashes.py --compare /tmp/before.json # on the new code

``--compare`` exits 1 and names the configurations and fingerprints that changed. One
torch thread (``--threads K``: K intra-op threads, as ``bench run --cell-threads K``, to check
which configurations stay bit for bit with a second core); about 15 s.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import torch

from algorithms.common.diagnostic_columns import DIAGNOSTIC_COLUMNS
from algorithms.common.episodes import MAPF_METRICS
from algorithms.registry import method_class
from envs.config import EnvConfig

MAP = "warehouse-10-20-10-2-1"
CASES: list[tuple[str, dict, str, int, str]] = [  # method, params, layout, N, on_goal
    ("hierarchical", {}, MAP, 24, "remove"),
    ("hierarchical", {"share_params": True, "fallback": "per_robot", "resample_on_fallback": True}, MAP, 24, "remove"),
    ("hierarchical", {"messages": "oracle", "ref_hold": 3}, "tiny", 6, "stay"),
    ("hierarchical", {"update_chunk": 16}, MAP, 24, "remove"),
    ("hierarchical", {"ref_advantage": "group", "ref_lr": 1e-3}, "tiny", 6, "stay"),
    ("decentralized", {}, MAP, 24, "remove"),
    ("decentralized", {"chunk_rows": 1024}, MAP, 24, "remove"),
    ("decentralized", {"safety_filter": True}, "tiny", 6, "stay"),
    ("ic3net", {}, MAP, 24, "remove"),
    ("ic3net", {"baseline": "per_robot", "optimizer": "rmsprop"}, "tiny", 6, "stay"),
    # protocol = "mappo" (a published run trains under it: reproduction/probe-mappo)
    ("hierarchical", {"protocol": "mappo"}, MAP, 24, "remove"),
    ("hierarchical", {"protocol": "mappo", "local_credit": "credit", "ppo_epochs": 2}, "tiny", 6, "stay"),
    ("decentralized", {"protocol": "mappo"}, MAP, 24, "remove"),
    ("ic3net", {"protocol": "mappo", "credit": "team"}, MAP, 24, "remove"),
]
FIELDS = ("train", "params", "eval")


def drop_later_metrics(rows: list[dict]) -> list[dict]:
    """The rows without the columns added after the baseline fingerprints (the MAPF metrics:
    derived from the same steps, checked by their own tests), so fingerprints stay comparable."""
    for row in rows:
        for name in MAPF_METRICS:
            row.pop(name, None)
    return rows


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:12]


def fingerprints(method: str, params: dict, layout: str, n: int, on_goal: str) -> dict[str, str]:
    env = EnvConfig.make(n_robots=n, layout=layout, horizon=60, loss_p=0.3, groups=min(4, n), on_goal=on_goal)
    m = method_class(method)(env, {"batch_episodes": 4, "eval_chunk": 3, **params}, seed=3)
    rows = [row for _ in range(3) for row in m.train_iteration()]
    for row in rows:  # wall times vary; the diagnostics are read-outs, not training
        for key in ("wall_s", *DIAGNOSTIC_COLUMNS):
            row.pop(key, None)
    drop_later_metrics(rows)
    weights = hashlib.sha256()
    for mod in m.modules().values():
        if isinstance(mod, torch.nn.Module):
            for name, t in mod.state_dict().items():
                weights.update(name.encode())
                weights.update(t.detach().contiguous().numpy().tobytes())
    evals = drop_later_metrics([row for mode in ("argmax", "sample", "sample@0.5")
                                for row in m.evaluate(0, execution=mode)])
    return {"train": _digest(json.dumps(rows, sort_keys=True, default=float).encode()),
            "params": weights.hexdigest()[:12],
            "eval": _digest(json.dumps(evals, sort_keys=True, default=float).encode())}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, help="write the fingerprints here (JSON)")
    ap.add_argument("--compare", type=Path, help="fingerprints from another checkout (JSON) to compare with")
    ap.add_argument("--threads", type=int, default=1, help="torch intra-op threads (default 1, the bench's)")
    args = ap.parse_args()
    if args.threads < 1:
        ap.error(f"--threads {args.threads}: must be at least 1")
    torch.set_num_threads(args.threads)
    got = {}
    for method, params, layout, n, on_goal in CASES:
        key = f"{method} {json.dumps(params, sort_keys=True)} {layout} N={n}"
        got[key] = fingerprints(method, params, layout, n, on_goal)
        print(key, *(got[key][f] for f in FIELDS), flush=True)
    if args.out:
        args.out.write_text(json.dumps(got, indent=1))
    if args.compare:
        want = json.loads(args.compare.read_text())
        changed = [f"{key}: {f}" for key in got for f in FIELDS if want.get(key, {}).get(f) != got[key][f]]
        print("\n".join(["changed:", *changed]) if changed else "bit for bit: every fingerprint unchanged")
        return 1 if changed else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
