"""Probe the reference layer of trained hierarchical cells (issue 18: does r carry information?).

    .venv/bin/python maintenance/probe_reference.py reproduction/paper [CELL_ID ...] [--episodes 10]

For every done hierarchical cell of the run (or the cells named) loads its checkpoint and
prints one JSON line: the cell's N, p, seed, variant parameters, training episodes, and
``scripts/reference_probe.py``'s ``probe_reference`` on evaluation scenarios (entropy of
mu, I(r; o), I(r; u_i | s), the share of the modal argmax r, success with argmax r vs a
uniform r). Evaluation streams only; the checkpoint is not modified.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import pandas as pd
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
from reference_probe import probe_reference  # noqa: E402  (scripts/reference_probe.py, a live probe library)

from algorithms.hierarchical.method import HierarchicalMethod
from bench.design.cells import Cell
from bench.execute.plan import cell_spec
from bench.execute.worker import build_method
from bench.store.checkpoints import load_checkpoint


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("cells", nargs="*")
    ap.add_argument("--episodes", type=int, default=10, help="evaluation episodes per probe (batches of 5)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    cells = pd.read_parquet(args.run / "cells.parquet")
    chosen = cells[(cells["method"] == "hierarchical") & (cells["status"] == "done")]
    if args.cells:
        chosen = cells[cells["cell_id"].isin(args.cells)]
    for row in chosen.itertuples():
        path = args.run / "checkpoints" / f"{row.cell_id}.pt"
        if not path.is_file():  # a committed run keeps only unfinished cells' checkpoints
            print(f"probe_reference: {row.cell_id}: no checkpoint in {path.parent}, skipped", file=sys.stderr)
            continue
        ckpt = load_checkpoint(str(path))
        cell = Cell.make(**json.loads(ckpt["cell"]))
        method = build_method(cell_spec(cell))
        if not isinstance(method, HierarchicalMethod):
            print(f"probe_reference: {row.cell_id} is a {cell.method} cell; only hierarchical ones have a reference",
                  file=sys.stderr)
            return 2
        method.load_state_dict(ckpt["state"])
        out = {"cell_id": row.cell_id, "n_robots": cell.n_robots, "loss_p": cell.loss_p, "seed": cell.seed,
               "ref_size": cell.ref_size, "params": dict(cell.params), "episodes": int(ckpt["episodes_done"])}
        out.update(probe_reference(method, batches=max(1, args.episodes // 5), batch_size=5, seed=1000))
        print(json.dumps(out), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
