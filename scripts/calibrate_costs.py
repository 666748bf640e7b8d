"""The effective rates a run's done cells observed (bench/design/cost_calibration.py), per method,
phase and N with their spread; ``--write`` stores them as the built-in rates of `bench
grids` (bench/design/cost_rates.json). Run it on the reproduction whenever its state is committed:

    .venv/bin/python scripts/calibrate_costs.py reproduction/paper --write
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from bench.design import costs
from bench.design.cost_calibration import observed_costs, rates_file


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--write", action="store_true", help=f"write {costs.RATES_FILE}")
    args = ap.parse_args()
    observed = observed_costs(args.run)
    for (method, n), g in observed.groupby(["method", "n_robots"]):
        for phase in ("train", "eval"):
            v = g[f"{phase}_rate"].dropna()
            if len(v):
                print(f"{method} N={n} {phase}: {len(v)} cells, median {v.median():,.0f}, "
                      f"{v.min():,.0f}-{v.max():,.0f} agent-steps/s")
    content = rates_file(observed, args.run.as_posix())
    if args.write:
        costs.RATES_FILE.write_text(json.dumps(content, indent=1) + "\n")
        print(f"wrote {costs.RATES_FILE}")


if __name__ == "__main__":
    main()
