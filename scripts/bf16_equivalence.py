"""The bf16 equivalence check of docs/decisions/0240: the probe trained both ways, its verdict.

Each seed of the probe is one bench cell trained and evaluated twice, with
``precision = "fp32"`` and with ``precision = "bf16"`` (decision 0241), by the bench's own
worker (``bench.execute.worker.CellWorker``: what ``bench run`` computes for the cell). The
outcome of a cell is its mean sample-mode success over its evaluation episodes; the test is
a paired TOST on d = success(bf16) - success(fp32) with margin 0.05 at alpha 0.05, from two
one-sided ``scipy.stats.ttest_1samp`` tests, per method. Every number of the check is fixed
in decision 0240; the options that change the configuration exist to test this script on a
tiny one, and a run with any of them says it is not the check.

The cost (worker-hours from the bench's cost model, ``bench grids``' rates) and the planned
power are printed first; ``--dry-run`` stops there. Cells run in pairs, seed by seed, so a
partial run holds whole pairs; each finished cell is written to ``OUT/cells/<cell_id>.json``
and skipped on a rerun (training checkpoints every ``--checkpoint-every`` updates to
``OUT/checkpoints/``, so a killed cell resumes). ``--shard I/K`` runs every K-th cell from
the I-th (0-based), for K processes on K cores. At the end ``OUT/rows.csv`` holds one row
per cell and ``OUT/verdict.json`` the verdict per method; the verdict is printed.

    .venv/bin/python scripts/bf16_equivalence.py --dry-run
    nice .venv/bin/python scripts/bf16_equivalence.py --out runs/bf16-equivalence --shard 0/2 &
    nice .venv/bin/python scripts/bf16_equivalence.py --out runs/bf16-equivalence --shard 1/2 &
    .venv/bin/python scripts/bf16_equivalence.py --out runs/bf16-equivalence --verdict-only
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from bench.design.cells import Cell
from bench.design.costs import cell_seconds
from envs.errors import BenchError

# docs/decisions/0240, fixed before the check ran
DELTA = 0.05  # equivalence margin on mean sample-mode success
ALPHA = 0.05
SEEDS = tuple(range(1000, 1020))  # 20 per arm, disjoint from the published grids' seeds
PROBE: dict[str, Any] = {"n_robots": 20, "loss_p": 0.2, "layout": "warehouse-10-20-10-2-1", "groups": 4,
                         "search_radius": 2, "c_max": 500, "episodes": 2000, "horizon": 500, "eval_episodes": 100}
METHODS = ("hierarchical", "decentralized", "ic3net")
PROTOCOL = "paper"
ARMS = ("fp32", "bf16")
PLANNING_SDS = (0.05, 0.07, 0.10)  # paired SDs the power is printed at (decision 0240, Basis)
OUTCOME, SECONDARY = "sample", "argmax"  # the deciding mode; the one reported beside it


def probe_cells(methods: tuple[str, ...], seeds: tuple[int, ...], probe: dict[str, Any], protocol: str,
                ) -> list[Cell]:
    """The check's cells, seed by seed (a partial run holds whole pairs): per seed, per method,
    the fp32 cell then the bf16 cell (only ``precision`` differs)."""
    base = {} if protocol == PROTOCOL else {"protocol": protocol}
    return [Cell.make(method=m, seed=s, **probe, params={**base, **({} if arm == "fp32" else {"precision": arm})})
            for s in seeds for m in methods for arm in ARMS]


def arm_of(cell: Cell) -> str:
    return str(cell.method_params().model_dump().get("precision", "fp32"))


def planned_power(sd: float, n: int, sims: int = 1000, seed: int = 0) -> float:
    """Share of ``sims`` simulated checks (n normal paired differences, mean 0, SD ``sd``)
    that conclude equivalence with ``tost``."""
    rng = np.random.default_rng(seed)
    return float(np.mean([tost(rng.normal(0.0, sd, n))["equivalent"] for _ in range(sims)]))


def tost(diffs: np.ndarray, delta: float = DELTA, alpha: float = ALPHA) -> dict[str, Any]:
    """Paired TOST on the differences: two one-sided one-sample t-tests (scipy), equivalent
    when both reject. Differences without spread (scipy gives no p-value): equivalent when
    their common value lies inside the margin."""
    d = np.asarray(diffs, dtype=np.float64)
    out: dict[str, Any] = {"pairs": len(d), "mean_diff": float(d.mean()) if len(d) else float("nan")}
    if len(d) < 2:
        return {**out, "p_low": float("nan"), "p_high": float("nan"), "ci90": [float("nan")] * 2,
                "equivalent": False}
    if np.ptp(d) == 0.0:
        inside = abs(float(d[0])) < delta
        return {**out, "p_low": 0.0 if inside else 1.0, "p_high": 0.0 if inside else 1.0,
                "ci90": [float(d[0])] * 2, "equivalent": inside}
    p_low = float(stats.ttest_1samp(d, -delta, alternative="greater").pvalue)  # H0: mean <= -delta
    p_high = float(stats.ttest_1samp(d, delta, alternative="less").pvalue)  # H0: mean >= +delta
    ci = stats.ttest_1samp(d, 0.0).confidence_interval(confidence_level=1 - 2 * alpha)
    return {**out, "p_low": p_low, "p_high": p_high, "ci90": [float(ci.low), float(ci.high)],
            "equivalent": max(p_low, p_high) < alpha}


def run_cell(cell: Cell, out: Path, checkpoint_every: int) -> dict[str, Any]:
    """Train and evaluate one cell with the bench's worker; its row."""
    import torch

    from bench.execute.plan import cell_spec
    from bench.execute.worker import CellWorker

    spec, worker = cell_spec(cell), CellWorker()
    ckpt = out / "checkpoints" / f"{cell.cell_id}.pt"
    state = torch.load(ckpt, weights_only=True) if ckpt.exists() else None
    iterations, train_cpu = (0, 0.0) if state is None else (int(state["iterations"]), float(state["cpu_s"]))
    while True:
        c0 = time.process_time()
        res = worker.train_chunk(spec, [] if state is None else [state["method"]], iterations, checkpoint_every)
        train_cpu += time.process_time() - c0
        iterations, state = int(res["iterations"]), {"method": res["state"], "iterations": res["iterations"],
                                                     "cpu_s": train_cpu}
        if res["finished"]:
            break
        ckpt.parent.mkdir(parents=True, exist_ok=True)
        torch.save(state, ckpt)
    c0 = time.process_time()
    chunks = -(-cell.eval_episodes // int(spec["params"]["eval_chunk"]))
    success = {mode: float(np.mean([r["success_rate"] for k in range(chunks)
                                    for r in worker.eval_chunk(spec, [state["method"]], k, mode)["rows"]]))
               for mode in (OUTCOME, SECONDARY)}
    ckpt.unlink(missing_ok=True)
    return {"cell_id": cell.cell_id, "method": cell.method, "seed": cell.seed, "precision": arm_of(cell),
            f"success_{OUTCOME}": success[OUTCOME], f"success_{SECONDARY}": success[SECONDARY],
            "train_cpu_s": train_cpu, "eval_cpu_s": time.process_time() - c0}


def verdict(rows: pd.DataFrame, methods: tuple[str, ...], seeds: tuple[int, ...]) -> dict[str, Any]:
    """Per method: the TOST on the deciding mode (complete pairs only count; a missing cell
    makes the check incomplete), the secondary mode's TOST and each arm's training CPU time."""
    out: dict[str, Any] = {}
    for m in methods:
        mine = rows[rows["method"] == m] if len(rows) else rows
        wide = mine.pivot_table(index="seed", columns="precision", values=[f"success_{OUTCOME}",
                                f"success_{SECONDARY}", "train_cpu_s"]) if len(mine) else pd.DataFrame()
        pairs = [s for s in seeds if not wide.empty and s in wide.index and all(
            (f"success_{OUTCOME}", a) in wide.columns and pd.notna(wide.loc[s, (f"success_{OUTCOME}", a)])
            for a in ARMS)]
        entry: dict[str, Any] = {"complete": len(pairs) == len(seeds), "pairs": len(pairs), "seeds": len(seeds)}
        if pairs:
            w = wide.loc[pairs]
            for mode in (OUTCOME, SECONDARY):
                entry[mode] = tost((w[(f"success_{mode}", "bf16")] - w[(f"success_{mode}", "fp32")]).to_numpy())
            entry["train_cpu_s"] = {a: float(w[("train_cpu_s", a)].mean()) for a in ARMS}
        entry["decision"] = ("incomplete" if not entry["complete"] else
                             "equivalent: bf16 allowed" if entry[OUTCOME]["equivalent"] else
                             "not shown equivalent: bf16 stays off")
        out[m] = entry
    return out


def print_verdict(result: dict[str, Any]) -> None:
    for m, e in result.items():
        line = f"{m}: {e['decision']} ({e['pairs']} of {e['seeds']} pairs)"
        if OUTCOME in e:
            t = e[OUTCOME]
            line += (f"; {OUTCOME} success d = {t['mean_diff']:+.4f}, 90% CI [{t['ci90'][0]:+.4f}, "
                     f"{t['ci90'][1]:+.4f}], TOST p = {max(t['p_low'], t['p_high']):.4g} (margin {DELTA}, "
                     f"alpha {ALPHA}); {SECONDARY}: d = {e[SECONDARY]['mean_diff']:+.4f}, "
                     f"p = {max(e[SECONDARY]['p_low'], e[SECONDARY]['p_high']):.4g}; training CPU s per cell "
                     f"fp32 {e['train_cpu_s']['fp32']:.0f}, bf16 {e['train_cpu_s']['bf16']:.0f}")
        print(line)


def parse_shard(text: str) -> tuple[int, int]:
    try:
        i, k = (int(v) for v in text.split("/"))
    except ValueError:
        i, k = -1, 0
    if k < 1 or not 0 <= i < k:
        raise BenchError(f"--shard {text!r}: give I/K with 0 <= I < K, e.g. 0/2")
    return i, k


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, help="folder of the cells' rows, rows.csv and verdict.json")
    ap.add_argument("--dry-run", action="store_true", help="print the cells' cost and the planned power only")
    ap.add_argument("--verdict-only", action="store_true", help="train nothing: the verdict of the rows in --out")
    ap.add_argument("--shard", default="0/1", help="I/K: run every K-th cell from the I-th (K processes)")
    ap.add_argument("--checkpoint-every", type=int, default=25, help="training updates between checkpoints")
    ap.add_argument("--power-sims", type=int, default=1000, help="simulated checks behind the planned power")
    test = ap.add_argument_group("a configuration other than decision 0240's (testing this script only)")
    test.add_argument("--methods", nargs="+", default=list(METHODS))
    test.add_argument("--seeds", type=int, default=len(SEEDS), help="the first K of the check's seeds")
    test.add_argument("--protocol", default=PROTOCOL, choices=["paper", "mappo"])
    test.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                      help=f"override a probe field ({', '.join(PROBE)})")
    args = ap.parse_args(argv)
    try:
        shard = parse_shard(args.shard)
        probe = dict(PROBE)
        for item in args.set:
            key, _, value = item.partition("=")
            if key not in PROBE or not value:
                raise BenchError(f"--set {item!r}: give KEY=VALUE with KEY one of {', '.join(PROBE)}")
            probe[key] = type(PROBE[key])(value)
        if args.seeds < 2 or args.seeds > len(SEEDS):
            raise BenchError(f"--seeds {args.seeds}: give 2 to {len(SEEDS)} "
                             f"(decision 0240's seeds {SEEDS[0]}-{SEEDS[-1]})")
        if args.checkpoint_every < 1:
            raise BenchError(f"--checkpoint-every {args.checkpoint_every}: give at least 1")
        if args.out is None and not args.dry_run:
            raise BenchError("--out: give the folder of the check's rows (or --dry-run)")
        methods, seeds = tuple(args.methods), SEEDS[: args.seeds]
        cells = probe_cells(methods, seeds, probe, args.protocol)
    except BenchError as exc:
        print(f"bf16_equivalence: {exc}", file=sys.stderr)
        return 2
    is_check = probe == PROBE and methods == METHODS and seeds == SEEDS and args.protocol == PROTOCOL
    hours = {m: sum(cell_seconds(c) for c in cells if c.method == m) / 3600 for m in methods}
    print(f"{'decision 0240' if is_check else 'NOT decision 0240 (a test configuration)'}: {len(cells)} cells "
          f"({len(seeds)} seeds x {len(methods)} methods x fp32/bf16), {args.protocol} protocol, "
          + ", ".join(f"{k}={v}" for k, v in probe.items()))
    print(f"cost: {sum(hours.values()):.1f} worker-hours ("
          + ", ".join(f"{m} {h:.1f}" for m, h in hours.items())
          + "; bench's cost model, fp32 rates for both arms, unstacked)")
    print(f"planned power (TOST, margin {DELTA}, alpha {ALPHA}, {len(seeds)} pairs, true difference 0): "
          + ", ".join(f"paired SD {sd}: {planned_power(sd, len(seeds), max(args.power_sims, 1)):.2f}"
                     for sd in PLANNING_SDS))
    if args.dry_run:
        return 0
    out: Path = args.out
    (out / "cells").mkdir(parents=True, exist_ok=True)
    if not args.verdict_only:
        i, k = shard
        for cell in cells[i::k]:
            path = out / "cells" / f"{cell.cell_id}.json"
            if path.exists():
                continue
            t0 = time.perf_counter()
            row = run_cell(cell, out, args.checkpoint_every)
            path.write_text(json.dumps(row, sort_keys=True) + "\n")
            print(f"{cell.method} seed {cell.seed} {row['precision']}: {OUTCOME} success "
                  f"{row[f'success_{OUTCOME}']:.3f} ({time.perf_counter() - t0:.0f} s)", flush=True)
    ids = {c.cell_id for c in cells}
    found = [json.loads(p.read_text()) for p in sorted((out / "cells").glob("*.json"))]
    rows = pd.DataFrame([r for r in found if r["cell_id"] in ids])
    rows.to_csv(out / "rows.csv", index=False)
    per_method = verdict(rows, methods, seeds)
    result = {"check": "decision 0240" if is_check else "test configuration", "margin": DELTA, "alpha": ALPHA,
              "methods": per_method}
    (out / "verdict.json").write_text(json.dumps(result, indent=2, sort_keys=True) + "\n")
    print_verdict(per_method)
    return 0


if __name__ == "__main__":
    sys.exit(main())
