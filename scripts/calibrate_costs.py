"""The effective rates a run's done cells observed (bench/design/cost_calibration.py), per method,
phase and N with their spread, and per method the worker-hours `bench grids` estimated for
the done cells against what they took; ``--write`` stores the rates as the built-in rates of
`bench grids` (bench/design/cost_rates.json). Run it on the reproduction whenever its state
is committed. The built-in rates come from the full grid's cells it trained itself (stacked by
3, scaled back to one seed), and from the cells it copied from the paper grid at the (method,
N) it trained none of:

    .venv/bin/python scripts/calibrate_costs.py reproduction/full --stack-seeds 3 \
        --exclude-run reproduction/paper --write
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import pandas as pd

from bench.design import costs
from bench.design.cost_calibration import estimate_vs_realized, observed_costs, rates_file
from bench.store.run_store import RunStore
from envs.errors import BenchError


def cells_of(run: Path) -> pd.DataFrame:
    """The run's ``cells.parquet`` rows; BenchError naming the folder without one."""
    cells = RunStore(run).read_cells()
    if cells is None:
        raise BenchError(f"no results store at {str(run)!r}: cells.parquet not found")
    return cells


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--write", action="store_true", help=f"write {costs.RATES_FILE}")
    ap.add_argument("--stack-seeds", type=int, default=1,
                    help="the run's bench run --stack-seeds (rates are scaled back to one seed; "
                         "the estimate stacks as the run did)")
    ap.add_argument("--exclude-run", type=Path,
                    help="the cells of this run were copied in (trained elsewhere): left out of the "
                         "estimate, and of the rates at every (method, N) this run trained itself")
    args = ap.parse_args()
    try:
        cells = cells_of(args.run)
        copied = cells_of(args.exclude_run)["cell_id"] if args.exclude_run is not None else ()
    except BenchError as exc:
        print(f"calibrate_costs: {exc}", file=sys.stderr)
        return 2
    observed = observed_costs(args.run, args.stack_seeds, copied)
    for (method, n), g in observed.groupby(["method", "n_robots"]):
        for phase in ("train", "eval"):
            v = g[f"{phase}_rate"].dropna()
            if len(v):
                print(f"{method} N={n} {phase}: {len(v)} cells, median {v.median():,.0f}, "
                      f"{v.min():,.0f}-{v.max():,.0f} agent-steps/s")
    table = estimate_vs_realized(cells, args.stack_seeds, exclude=copied)
    print("worker-hours of the done cells, estimated with the built-in rates (bench grids) and realized "
          "(their wall_s):")
    for r in table.itertuples(index=False):
        print(f"  {r.method}: {r.cells} cells, estimated {r.estimated_h:.2f} h, realized {r.realized_h:.2f} h "
              f"(x{r.ratio:.2f})")
    content = rates_file(observed, args.run.as_posix(), args.stack_seeds,
                         args.exclude_run.as_posix() if args.exclude_run is not None else None)
    if args.write:
        costs.RATES_FILE.write_text(json.dumps(content, indent=1) + "\n")
        print(f"wrote {costs.RATES_FILE}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
