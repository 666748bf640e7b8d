"""Fig. 3: communication payload per step, and the payload ratio against (Z-1)/(N-1).

(a) scalars transmitted per step vs N for the hierarchical method, the decentralized
all-to-all baseline and IC3Net (its gated broadcast, counted per step from the gates that
are open), with the analytical N (Z-1) d_m and N (N-1) d_m as dotted lines;
(b) C_hier / C_dec vs the analytical bound (Z-1)/(N-1) of Sec. III-A (the inequality
after eq:gru_pred_loss, "C_hier <= N(Z-1)d_m"). The hierarchical and decentralized payloads
are the channel's accounting (every scalar on every link each step, lost or not:
envs/channel.py, algorithms/common/all_to_all.py), i.e. the formula, not a count of the
messages sent, so (b) is labelled as the accounted ratio, never as a measured one. Payloads are
means over evaluation episodes (all seeds) at p = 0.2 when the run has it, else over
every p. C_dec is the decentralized method's measured payload at the same N when the run
has it, else the all-to-all reference the channel reports (``payload_dec_per_step``).
Ticks sit on the measured team sizes only; the two panels are stacked, each a column wide,
and a tick label is left out where it would touch its neighbour (``reports.figures.ticks``).
"""
from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.ticker import FixedLocator

from paper.data.payload import payload_points
from paper.settings import PAPER_FIG3_P
from reports.data.store import fmt_p, select
from reports.figures.plotting import (
    Built,
    method_color,
    method_label,
    method_style,
    new_figure,
    paper_style,
    placeholder,
)
from reports.figures.seed_counts import counts_text, seed_counts
from reports.figures.ticks import log_ticks, spaced_formatter

BASELINES = ("decentralized", "ic3net")  # measured payload per step, drawn beside hierarchical
MARKERS = {"hierarchical": "o", "decentralized": "s", "ic3net": "^"}
RATIO_LABEL = "C$_{hier}$ / C$_{dec}$ as accounted (formula)"


def _caption(pts: pd.DataFrame, ev: pd.DataFrame) -> str:
    """Fig. 3's caption: p, seeds per team size and episodes behind each point."""
    if pts.empty:
        return "Fig. 3: communication payload; the run has no hierarchical evaluation rows."
    p = pts["p_used"].iloc[0]
    parts = []
    for method in ("hierarchical", *BASELINES):
        rows = select(ev, method)
        if len(rows):
            eps = rows.groupby(["cell_id", "execution"])["episode"].size()
            parts.append(f"{method_label(method)}: {counts_text(seed_counts(rows, ['n_robots']))} "
                         f"({'/'.join(map(str, sorted(set(eps))))} evaluation episodes per seed and execution "
                         f"mode, modes pooled: {', '.join(sorted(set(rows['execution'])))})")
    ptxt = f"p = {p}" if p != "all" else "pooled over every p"
    return (f"Fig. 3: (a) scalars transmitted per step (mean over evaluation episodes and seeds, {ptxt}) "
            "against team size, dotted lines the analytical N(Z-1)d_m and N(N-1)d_m; (b) C_hier / C_dec "
            "against the bound (Z-1)/(N-1). The hierarchical and decentralized payloads are the channel's "
            "accounting (every scalar on every link each step, lost or not), i.e. the formula, not counted "
            "from the messages, so (b) shows the accounted ratio, which equals the bound by construction; "
            "IC3Net's payload is counted from the gates that are open. Seeds: " + "; ".join(parts)
            + ". Points are means; no band is drawn (the per-episode spread is in summary.csv).")


def fig3_payload(evals: pd.DataFrame) -> Built:
    """Build Fig. 3 from evaluation rows joined with their cell config."""
    notes: list[str] = []
    pts = payload_points(evals)
    ev = select(evals, loss_p=PAPER_FIG3_P) if len(pts) and pts["p_used"].iloc[0] != "all" else evals
    base = {m: select(ev, m).groupby("n_robots")["payload_scalars_per_step"].mean() for m in BASELINES}
    dec = base["decentralized"]
    if pts.empty:
        notes.append("the run has no hierarchical evaluation rows: nothing to plot")
    elif pts["p_used"].iloc[0] == "all":
        notes.append(f"no p = {fmt_p(PAPER_FIG3_P)} in the run; payloads pooled over every p")
    if dec.empty:
        notes.append("no decentralized evaluation rows: C_dec is the all-to-all reference N(N-1)d_m")
    if base["ic3net"].empty:
        notes.append("no IC3Net evaluation rows: IC3Net is absent from (a)")
    caption = _caption(pts, ev)
    with paper_style():
        fig = new_figure(4.4)
        ax_a, ax_b = fig.subplots(2, 1, height_ratios=[1.25, 1.0])
        if pts.empty:
            placeholder(ax_a, "no hierarchical\nevaluation data")
            placeholder(ax_b, "no hierarchical\nevaluation data")
            return Built(fig, notes, caption)
        measured = sorted({int(n) for n in pts["n_robots"]} | {int(n) for s in base.values() for n in s.index})
        ns = np.asarray(measured, dtype=np.float64)
        lo_n, hi_n = max(ns.min(), 2.0), ns.max()
        if hi_n - lo_n < 2:
            lo_n, hi_n = max(2.0, lo_n - 2), hi_n + 2
        grid = np.linspace(lo_n, hi_n, 60)
        d_m = float(np.nanmean(pts["d_m"]))
        for m, xs, ys in (("hierarchical", pts["n_robots"], pts["c_hier"]),
                          *((m, base[m].index, base[m].to_numpy()) for m in BASELINES if not base[m].empty)):
            ax_a.plot(xs, ys, marker=MARKERS[m], ls=method_style(m), color=method_color(m), label=method_label(m))
        for z in sorted(set(pts["groups"])):
            ax_a.plot(grid, grid * (z - 1) * d_m, ":", color=method_color("hierarchical"),
                      lw=0.8, label=f"N(Z-1)d$_m$, Z={z}")
        ax_a.plot(grid, grid * (grid - 1) * d_m, ":", color=method_color("decentralized"), lw=0.8,
                  label="N(N-1)d$_m$")
        ax_a.set_yscale("log")
        log_ticks(ax_a)
        ax_a.set_ylabel("payload (scalars / step)")
        ax_a.set_title("(a) payload per step", loc="left")

        for z in sorted(set(pts["groups"])):
            ax_b.plot(grid, (z - 1) / (grid - 1), "--", color="0.3", lw=0.8,
                      label="bound (Z-1)/(N-1)" + (f", Z={z}" if pts["groups"].nunique() > 1 else ""))
        ax_b.plot(pts["n_robots"], pts["ratio"], "o", color=method_color("hierarchical"), label=RATIO_LABEL)
        ax_b.set_ylabel("C$_{hier}$ / C$_{dec}$")
        ax_b.set_ylim(bottom=0)
        ax_b.set_title("(b) payload ratio (accounted: the bound by construction)", loc="left")
        handles, labels = [], []
        for ax in (ax_a, ax_b):
            h, lab = ax.get_legend_handles_labels()
            handles += h
            labels += lab
        fig.legend(handles, labels, loc="outside lower center", ncol=2, frameon=False,
                   handlelength=2.2, columnspacing=1.0)
        for ax in (ax_a, ax_b):  # ticks on the measured team sizes only, labels never touching
            ax.set_xlim(lo_n - 0.04 * (hi_n - lo_n), hi_n + 0.04 * (hi_n - lo_n))
            ax.xaxis.set_minor_locator(FixedLocator([]))
            spaced_formatter(ax, measured, 0.08)
            ax.set_xlabel("team size N (robots)")
    return Built(fig, notes, caption)
