"""Fig. 2: success-rate percentile curves, hierarchical vs IC3Net.

Panels: N = 40, 60 (rows) x p = 0.2, 0.4, 0.6 (columns), paper Sec. IV, fig:fig2: one
figure per execution mode of the run (``fig2_modes``: argmax, sample, sample@T; both
methods in a panel ran the same mode on the same scenarios), so no figure has more than
the paper's six panels. As in the paper, the evaluation episodes of a configuration are
sorted by success rate (fraction of robots that reached their goal) and plotted against
their percentile. Each seed's quantile curve on a 101-point percentile grid (Hazen
positions) is drawn as a thin line and their mean over seeds (the estimator of the
claims' Fig. 2 checks) as a bold line in the method's style. No t band: at 3 seeds its
half-width is 2.5 seed standard deviations (t = 4.30 over sqrt(3)), so about 8 of 18 bands
spanned 0-100% and hid the curves; the seeds themselves show the spread. The caption names the seeds of every
configuration per method.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.artist import Artist

from paper.settings import PAPER_FIG2_N, PAPER_FIG2_P
from reports.data.store import execution_order, fmt_p, select
from reports.figures.plotting import (
    FONT_PT,
    Built,
    choose,
    fmt_list,
    label_order,
    method_color,
    method_label,
    method_style,
    new_figure,
    paper_style,
    placeholder,
)
from reports.figures.seed_counts import counts_text, seed_counts
from reports.stats import quantile_curve

METHODS = ("hierarchical", "ic3net")
SEED_LW, MEAN_LW = 0.45, 1.4  # thin per-seed curves, bold mean
GRID = np.linspace(0.0, 100.0, 101)  # percentiles at which seed curves are compared


def seed_quantile_curves(evals: pd.DataFrame, metric: str = "success_rate") -> np.ndarray:
    """(S, G) quantile curve of ``metric`` on ``GRID`` for each cell (seed) of ``evals``."""
    return np.stack([quantile_curve(g[metric].to_numpy(), GRID)
                     for _, g in evals.groupby("cell_id", sort=True)])


def fig2_modes(evals: pd.DataFrame) -> list[str]:
    """Execution modes of the hierarchical and IC3Net rows in report order (one figure each);
    ``["argmax"]`` when there are none, so the figure still says so."""
    return execution_order(evals[evals["method"].isin(METHODS)]["execution"]) or ["argmax"]


def _caption(mode: str, rows: pd.DataFrame, eps: set[int]) -> str:
    """Fig. 2's caption: the mode, seeds per configuration per method, episodes, the lines."""
    parts = [f"{method_label(m)}: {counts_text(seed_counts(rows[rows['method'] == m]))}"
             for m in METHODS if (rows["method"] == m).any()]
    if not parts:
        return (f"Fig. 2 ({mode} execution): success-rate percentile curves; the run has no hierarchical "
                "or IC3Net evaluation.")
    return (f"Fig. 2 ({mode} execution): success rate (% of robots at goal) of evaluation episodes against "
            "their percentile, per team size N (rows) and loss probability p (columns). Seeds: "
            + "; ".join(parts) + f"; {'/'.join(map(str, sorted(eps)))} evaluation episodes per seed. "
            "Thin lines: each seed's quantile curve; bold line: their mean over seeds. No confidence band "
            "(at 3 seeds the half-width of a 95% t band is 2.5 seed standard deviations); the claims page "
            "tests the difference.")


def fig2_success(evals: pd.DataFrame, mode: str | None = None) -> Built:
    """Build Fig. 2 for one execution mode (default: the first of ``fig2_modes``) from
    evaluation rows joined with their cell config."""
    notes: list[str] = []
    both = evals[evals["method"].isin(METHODS)]
    mode = mode or fig2_modes(evals)[0]
    ns, n_missing = choose(PAPER_FIG2_N, set(both["n_robots"]), 2, largest=True)
    ps, p_missing = choose(PAPER_FIG2_P, set(both["loss_p"].astype(float)), 3)
    if n_missing:
        notes.append(f"the run has no hierarchical or IC3Net evaluation for N = {fmt_list(n_missing)}")
    if p_missing:
        notes.append(f"the run has no hierarchical or IC3Net evaluation at p = {fmt_list(p_missing)}")
    in_mode = both[both["execution"] == mode]
    nrow, ncol = max(len(ns), 1), max(len(ps), 1)
    drawn_rows, eps = [], set()
    with paper_style():
        fig = new_figure(0.9 + 1.3 * nrow)
        axes = fig.subplots(nrow, ncol, sharex=True, sharey=True, squeeze=False)
        handles: dict[str, Artist] = {}
        for i in range(nrow):
            for j in range(ncol):
                ax = axes[i, j]
                if i >= len(ns) or j >= len(ps):
                    placeholder(ax, "no evaluation data")
                    continue
                n, p = int(ns[i]), float(ps[j])
                drawn = False
                for method in METHODS:
                    rows = select(in_mode, method, n, p)
                    if rows.empty:
                        notes.append(f"N = {n}, p = {fmt_p(p)}, {mode}: no {method} evaluation")
                        continue
                    curves = seed_quantile_curves(rows)  # (S, G)
                    color, z = method_color(method), 2 + 2 * METHODS.index(method)
                    for seed_curve in curves:
                        ax.plot(GRID, 100 * seed_curve, color=color, lw=SEED_LW, alpha=0.7,
                                label="_seed", zorder=z)
                    (line,) = ax.plot(GRID, 100 * curves.mean(axis=0), color=color, lw=MEAN_LW,
                                      label=method_label(method), ls=method_style(method), zorder=z + 1)
                    handles.setdefault(method_label(method), line)
                    drawn_rows.append(rows[["method", "n_robots", "loss_p", "cell_id"]].drop_duplicates())
                    eps.update(rows.groupby("cell_id").size().tolist())
                    drawn = True
                if not drawn:
                    placeholder(ax, "no data")
                ax.set_title(f"N = {n}, p = {fmt_p(p)}")
                ax.set_xlim(0, 100)
                ax.set_ylim(-3, 103)
                ax.set_xticks([0, 50, 100])
                ax.set_yticks([0, 50, 100])
        fig.supxlabel("evaluation episode percentile (%)", fontsize=FONT_PT)
        fig.supylabel("success rate (% of robots at goal)", fontsize=FONT_PT)
        order = sorted(handles, key=label_order)
        fig.legend([handles[k] for k in order], order, loc="outside upper center",
                   ncol=max(len(handles), 1), frameon=False, handlelength=2.5,
                   title=f"{mode} execution; thin: one seed, bold: mean over seeds")
    drawn_df = pd.concat(drawn_rows) if drawn_rows else both.iloc[0:0]
    return Built(fig, notes, _caption(mode, drawn_df, eps))
