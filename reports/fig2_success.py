"""Fig. 2: success-rate percentile curves, hierarchical vs IC3Net.

Panels: N = 40, 60 (rows) x p = 0.2, 0.4, 0.6 (columns), paper Sec. IV, fig:fig2, repeated
for every execution mode of the run (rows grouped by mode: argmax, sample, sample@T; both
methods in a panel ran the same mode on the same scenarios). As in
the paper, the evaluation episodes of a configuration are sorted by success rate (fraction
of robots that reached their goal) and plotted against their percentile. Episodes of all
seeds are pooled for the curve; with several seeds a 95% bootstrap band over seeds (each
seed's quantile curve resampled) is drawn around it.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from reports.plotting import (
    FONT_PT,
    Built,
    choose,
    fmt_list,
    label_order,
    method_color,
    method_label,
    new_figure,
    paper_style,
    placeholder,
)
from reports.stats import bootstrap_band, percentile_curve, quantile_curve
from reports.store import execution_order, fmt_p, select

PAPER_N = (40, 60)
PAPER_P = (0.2, 0.4, 0.6)
METHODS = ("hierarchical", "ic3net")
STYLES = {"hierarchical": "-", "ic3net": "--"}  # dashed on top of solid: ties stay visible
GRID = np.linspace(0.0, 100.0, 101)  # percentiles at which seed curves are compared


def seed_quantile_curves(evals: pd.DataFrame, metric: str = "success_rate") -> np.ndarray:
    """(S, G) quantile curve of ``metric`` on ``GRID`` for each cell (seed) of ``evals``."""
    return np.stack([quantile_curve(g[metric].to_numpy(), GRID)
                     for _, g in evals.groupby("cell_id", sort=True)])


def fig2_success(evals: pd.DataFrame) -> Built:
    """Build Fig. 2 from evaluation rows joined with their cell config."""
    notes: list[str] = []
    both = evals[evals["method"].isin(METHODS)]
    ns, n_missing = choose(PAPER_N, set(both["n_robots"]), 2, largest=True)
    ps, p_missing = choose(PAPER_P, set(both["loss_p"].astype(float)), 3)
    if n_missing:
        notes.append(f"the run has no hierarchical or IC3Net evaluation for N = {fmt_list(n_missing)}")
    if p_missing:
        notes.append(f"the run has no hierarchical or IC3Net evaluation at p = {fmt_list(p_missing)}")
    modes = execution_order(both["execution"]) or ["argmax"]
    per_mode = max(len(ns), 1)
    nrow, ncol = per_mode * len(modes), max(len(ps), 1)
    with paper_style():
        fig = new_figure(1.0 + 1.25 * nrow)
        axes = fig.subplots(nrow, ncol, sharex=True, sharey=True, squeeze=False)
        handles: dict[str, object] = {}
        for i in range(nrow):
            mode, i_n = modes[i // per_mode], i % per_mode
            in_mode = both[both["execution"] == mode]
            for j in range(ncol):
                ax = axes[i, j]
                if i_n >= len(ns) or j >= len(ps):
                    placeholder(ax, "no evaluation data")
                    continue
                n, p = int(ns[i_n]), float(ps[j])
                drawn = False
                for method in METHODS:
                    rows = select(in_mode, method, n, p)
                    if rows.empty:
                        notes.append(f"N = {n}, p = {fmt_p(p)}, {mode}: no {method} evaluation")
                        continue
                    pct, val = percentile_curve(rows["success_rate"].to_numpy())
                    color = method_color(method)
                    (line,) = ax.plot(pct, 100 * val, color=color, label=method_label(method),
                                      drawstyle="steps-mid", ls=STYLES[method], zorder=2 + METHODS.index(method))
                    handles.setdefault(method_label(method), line)
                    if rows["cell_id"].nunique() > 1:
                        _, lo, hi = bootstrap_band(seed_quantile_curves(rows))
                        ax.fill_between(GRID, 100 * lo, 100 * hi, color=color, alpha=0.25, lw=0)
                    drawn = True
                if not drawn:
                    placeholder(ax, "no data")
                ax.set_title(f"N = {n}, p = {fmt_p(p)}\n{mode}")
                ax.set_xlim(0, 100)
                ax.set_ylim(-3, 103)
                ax.set_xticks([0, 50, 100])
                ax.set_yticks([0, 50, 100])
        fig.supxlabel("evaluation episode percentile (%)", fontsize=FONT_PT)
        fig.supylabel("success rate (% of robots at goal)", fontsize=FONT_PT)
        if handles:
            order = sorted(handles, key=label_order)
            fig.legend([handles[k] for k in order], order, loc="outside upper center",
                       ncol=len(handles), frameon=False)
    return Built(fig, notes)
