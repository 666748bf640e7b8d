"""Fig. 2: success-rate percentile curves, hierarchical vs IC3Net.

Panels: N = 40, 60 (rows) x p = 0.2, 0.4, 0.6 (columns), paper Sec. IV, fig:fig2, repeated
for every execution mode of the run (rows grouped by mode: argmax, sample, sample@T; both
methods in a panel ran the same mode on the same scenarios). As in
the paper, the evaluation episodes of a configuration are sorted by success rate (fraction
of robots that reached their goal) and plotted against their percentile. Line and band
come from one estimator: each seed's quantile curve on a 101-point percentile grid (Hazen
positions), the line their mean over seeds and, with two or more seeds, the band a 95%
Student t interval over seeds of that same mean (so the line always lies inside its
band). The caption gives the seed and episode counts per method.
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
from reports.stats import quantile_curve, t_band
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


def _caption(counts: dict[str, tuple[set[int], set[int]]], modes: list[str]) -> str:
    """Fig. 2's caption: seeds and episodes per method, the estimator and the band."""
    parts = []
    for method in METHODS:
        seeds, eps = counts.get(method, (set(), set()))
        if seeds:
            parts.append(f"{method_label(method)}: {'/'.join(map(str, sorted(seeds)))} seed(s) x "
                         f"{'/'.join(map(str, sorted(eps)))} evaluation episodes per seed")
    if not parts:
        return "Fig. 2: success-rate percentile curves; the run has no hierarchical or IC3Net evaluation."
    return ("Fig. 2: success rate (% of robots at goal) of evaluation episodes against their percentile, "
            f"per team size N (rows), loss probability p (columns) and execution mode ({', '.join(modes)}). "
            + "; ".join(parts) + ". Line: mean over seeds of each seed's quantile curve; shaded band: "
            "95% Student t interval over seeds of that mean, cut at 0 and 100% (none with one seed; "
            "with two seeds the t quantile is 12.7, so the band is wide).")


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
        counts: dict[str, tuple[set[int], set[int]]] = {}
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
                    mean, lo, hi = t_band(seed_quantile_curves(rows))
                    color = method_color(method)
                    (line,) = ax.plot(GRID, 100 * mean, color=color, label=method_label(method),
                                      ls=STYLES[method], zorder=2 + METHODS.index(method))
                    handles.setdefault(method_label(method), line)
                    seeds, eps = counts.setdefault(method, (set(), set()))
                    seeds.add(rows["cell_id"].nunique())
                    eps.update(rows.groupby("cell_id").size().tolist())
                    if np.isfinite(lo).any():
                        ax.fill_between(GRID, 100 * np.clip(lo, 0, 1), 100 * np.clip(hi, 0, 1),
                                        color=color, alpha=0.25, lw=0)  # a success rate is in 0..100%
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
    return Built(fig, notes, _caption(counts, modes))
