"""Fig. 1: training convergence (smoothed team return vs training episode).

(a) hierarchical vs decentralized for N = 20, 40, 60; (b) hierarchical for N = 80, 90,
100; both at p = 0.2 (paper Sec. IV, fig:fig1). Each curve is the trailing moving average
of the team return (eq:reward summed over the episode); with several seeds, the mean over
seeds and a pointwise 95% Student t band over seeds. Configurations the run lacks are named in the
notes; a run with other team sizes (e.g. smoke) plots the ones it has in (a). Panel (b) is
drawn only when the run has hierarchical training data at N = 80-100: it never re-plots
(a)'s team sizes. The caption names p, seeds, episodes, the smoothing window and the band.
"""
from __future__ import annotations

from typing import cast

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.ticker import FuncFormatter, MaxNLocator

from paper.settings import PAPER_FIG1_P, PAPER_FIG1A_N, PAPER_FIG1B_N
from reports.data.store import fmt_p, select
from reports.figures.learning_curves import Curve, draw_curve, smoothing_text, training_curve
from reports.figures.plotting import (
    FONT_PT,
    Built,
    choose,
    fmt_list,
    method_color,
    method_label,
    method_style,
    new_figure,
    paper_style,
    placeholder,
    ranked_legend,
    shades,
    thousands,
)
from reports.figures.seed_counts import counts_text
from reports.figures.ylimits import fit_ylims

B_STYLES = ("-", "--", ":")  # (b): one line style per team size, beside its shade


def _pick_p(train: pd.DataFrame) -> tuple[float | None, list[str]]:
    ps = sorted(set(train["loss_p"].dropna().astype(float)))
    if not ps:
        return None, []
    if any(np.isclose(PAPER_FIG1_P, q) for q in ps):
        return PAPER_FIG1_P, []
    return ps[0], [f"the run has no p = {fmt_p(PAPER_FIG1_P)}; showing p = {fmt_p(ps[0])}"]


def _caption(p: str, curves: list[tuple[str, int, Curve]], has_b: bool, own_y: bool) -> str:
    """Fig. 1's caption: configuration, seeds per configuration, episodes, smoothing, band."""
    if not curves:
        return f"Fig. 1: training convergence at p = {p}; the run has no training data to plot."
    eps = sorted({int(c.episode.max()) + 1 for _, _, c in curves})
    wins = sorted({c.window for _, _, c in curves})
    what = "(a) hierarchical (ours) vs decentralized" + (", (b) hierarchical (ours) at N = 80-100" if has_b else "")
    seeds = []
    for method in dict.fromkeys(m for m, _, _ in curves):
        counts: dict[tuple[float, ...], int] = {(float(n),): c.seeds for m, n, c in curves if m == method}
        seeds.append(f"{method_label(method)}: {counts_text(counts)}")
    band = ("shaded band: pointwise 95% Student t interval over seeds of the mean curve, its edges thin lines"
            if max(c.seeds for _, _, c in curves) > 1 else "no band (one seed per configuration)")
    scale = " Each panel of (a) has its own y-scale (their ranges differ)." if own_y else ""
    return (f"Fig. 1: training convergence, {what}, at p = {p}. Team return per training episode, "
            f"{smoothing_text(wins)}; line: mean over seeds ({'; '.join(seeds)}; "
            f"{'/'.join(map(str, eps))} training episodes each); {band}.{scale}")


def _episode_axis(ax: Axes, nbins: int) -> None:
    ax.xaxis.set_major_locator(MaxNLocator(nbins=nbins, steps=[1, 2, 5, 10], integer=True))
    ax.xaxis.set_major_formatter(FuncFormatter(thousands))


def fig1_training(train: pd.DataFrame) -> Built:
    """Build Fig. 1 from training rows joined with their cell config (reports.data.store)."""
    notes: list[str] = []
    p, pnote = _pick_p(train)
    notes += pnote
    at_p = select(train, loss_p=p) if p is not None else train.iloc[0:0]
    ab_ns = set(select(at_p, "hierarchical")["n_robots"]) | set(select(at_p, "decentralized")["n_robots"])
    a_ns, a_missing = choose(PAPER_FIG1A_N, ab_ns, 3)
    hier_ns = {int(n) for n in select(at_p, "hierarchical")["n_robots"]}
    b_ns = [n for n in PAPER_FIG1B_N if n in hier_ns]  # (b) only at the paper's N = 80-100
    b_missing = [n for n in PAPER_FIG1B_N if n not in hier_ns]
    ptxt = fmt_p(p) if p is not None else fmt_p(PAPER_FIG1_P)
    if a_missing:
        notes.append(f"(a) the run has no training data for N = {fmt_list(a_missing)} at p = {ptxt}")
    if b_missing:
        notes.append(f"(b) the run has no hierarchical training data for N = {fmt_list(b_missing)} at p = {ptxt}"
                     + ("; panel (b) is omitted" if not b_ns else ""))
    drawn_curves: list[tuple[str, int, Curve]] = []

    with paper_style():
        fig = new_figure(3.7 if b_ns else 1.9)
        ncol = max(len(a_ns), 1)
        if b_ns:
            top, bottom = cast("np.ndarray", fig.subfigures(2, 1, height_ratios=[1.0, 1.1]))  # (2,) of SubFigure
        else:
            top, bottom = fig, None
        axes_a = list(top.subplots(1, ncol, squeeze=False)[0])
        with_data = []
        for k, ax in enumerate(axes_a):
            if k >= len(a_ns):
                placeholder(ax, f"no training data\nat p = {ptxt}")
                continue
            n = int(a_ns[k])
            drawn = False
            for method in ("hierarchical", "decentralized"):
                c = training_curve(at_p, method, n, p)
                if c is None:
                    notes.append(f"(a) N = {n}: no {method} training data at p = {ptxt}")
                    continue
                draw_curve(ax, c, method_color(method), method_label(method), method_style(method))
                drawn_curves.append((method, n, c))
                drawn = True
            if not drawn:
                placeholder(ax, "no data")
            else:
                with_data.append(ax)
            ax.set_title(f"N = {n}")
            _episode_axis(ax, 3)
            ax.yaxis.set_major_locator(MaxNLocator(nbins=4))
        own_y = fit_ylims(with_data) and len(with_data) > 1
        axes_a[0].set_ylabel("team return")
        top.supxlabel("training episode", fontsize=FONT_PT)
        handles, order = ranked_legend(axes_a)
        if handles:
            top.legend(handles, order, loc="outside upper center",
                       ncol=len(handles), frameon=False, handlelength=2.5, columnspacing=1.0)
        if bottom is not None:
            axes_a[0].annotate("(a)", (0.0, 1.0), xycoords="axes fraction", xytext=(-18, 4),
                               textcoords="offset points", fontweight="bold", va="bottom")
            ax_b = bottom.subplots()
            colors = shades("hierarchical", b_ns, spread=0.5)
            for k, n in enumerate(b_ns):
                c = training_curve(at_p, "hierarchical", int(n), p)
                if c is not None:
                    draw_curve(ax_b, c, colors[int(n)], f"N = {int(n)}", B_STYLES[k % len(B_STYLES)],
                          band_alpha=0.12)
                    drawn_curves.append(("hierarchical", int(n), c))
            ax_b.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False,
                        title=method_label("hierarchical").replace(" (", "\n("), handlelength=2.5,
                        borderaxespad=0.2)
            _episode_axis(ax_b, 5)
            ax_b.set_xlabel("training episode")
            ax_b.set_ylabel("team return")
            ax_b.annotate("(b)", (0.0, 1.0), xycoords="axes fraction", xytext=(-18, 4),
                          textcoords="offset points", fontweight="bold", va="bottom")
    return Built(fig, notes, _caption(ptxt, drawn_curves, bool(b_ns), own_y))
