"""Print the effective rates a run's done cells observed, as the literal of
``bench/costs.py``'s ``AGENT_STEPS_PER_S`` (2 significant digits), with each (method, N)'s
number of cells and spread, so the built-in rates can be rebuilt from the reproduction:

    .venv/bin/python scripts/calibrate_costs.py reproduction/paper
"""
from __future__ import annotations

import argparse
import math

from bench.cost_calibration import observed_costs, observed_rates


def two_digits(x: float) -> float:
    return round(x, 1 - int(math.floor(math.log10(abs(x))))) if x else 0.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run")
    args = ap.parse_args()
    observed = observed_costs(args.run)
    for (method, n), g in observed.groupby(["method", "n_robots"]):
        for phase in ("train", "eval"):
            v = g[f"{phase}_rate"].dropna()
            if len(v):
                print(f"# {method} N={n} {phase}: {len(v)} cells, {v.min():,.0f}-{v.max():,.0f} agent-steps/s")
    rates = observed_rates(observed)
    print("AGENT_STEPS_PER_S = {")
    for method, phases in rates.items():
        inner = ", ".join(f'"{ph}": {{{", ".join(f"{n}: {two_digits(r):_.1f}" for n, r in pts.items())}}}'
                          for ph, pts in phases.items())
        print(f'    "{method}": {{{inner}}},')
    print("}")


if __name__ == "__main__":
    main()
