"""Fig. 1: training convergence (smoothed episode reward vs training episode).

(a) hierarchical vs decentralized for N = 20, 40, 60; (b) hierarchical for N = 80, 90,
100; both at p = 0.2 (paper Sec. IV, fig:fig1). Each curve is the trailing moving average
of the team return (eq:reward summed over the episode); with several seeds, the mean over
seeds and a 95% bootstrap band over seeds. Configurations the run lacks are named in the
notes; a run with other team sizes (e.g. smoke) plots the ones it has.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.ticker import FuncFormatter, MaxNLocator

from reports.plotting import (
    FONT_PT,
    Built,
    choose,
    fmt_list,
    label_order,
    method_color,
    method_label,
    n_palette,
    new_figure,
    paper_style,
    placeholder,
    thousands,
)
from reports.stats import bootstrap_band, smooth, smoothing_window
from reports.store import fmt_p, select

PAPER_A_N = (20, 40, 60)
PAPER_B_N = (80, 90, 100)
PAPER_P = 0.2


@dataclass(frozen=True)
class Curve:
    """A smoothed training curve: episodes (T,), mean/lo/hi (T,) over ``seeds`` runs."""

    episode: np.ndarray
    mean: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    seeds: int


def training_curve(train: pd.DataFrame, method: str, n: int, p: float,
                   metric: str = "team_return") -> Curve | None:
    """Smoothed ``metric`` per episode for one (method, N, p), over the cells (seeds) present."""
    rows = select(train, method, n, p)
    if rows.empty:
        return None
    wide = rows.pivot_table(index="episode", columns="cell_id", values=metric, aggfunc="mean")
    wide = wide.sort_index()
    window = smoothing_window(len(wide))
    curves = np.stack([smooth(wide[c].to_numpy(), window) for c in wide.columns])  # (S, T)
    curves[np.isnan(wide.to_numpy().T)] = np.nan  # keep gaps of shorter runs as gaps
    mean, lo, hi = bootstrap_band(curves)
    return Curve(wide.index.to_numpy(), mean, lo, hi, curves.shape[0])


def _draw(ax: Axes, curve: Curve, color: tuple[float, float, float], label: str) -> None:
    ax.plot(curve.episode, curve.mean, color=color, label=label)
    if curve.seeds > 1:
        ax.fill_between(curve.episode, curve.lo, curve.hi, color=color, alpha=0.25, lw=0)


def _pick_p(train: pd.DataFrame) -> tuple[float | None, list[str]]:
    ps = sorted(set(train["loss_p"].dropna().astype(float)))
    if not ps:
        return None, []
    if any(np.isclose(PAPER_P, q) for q in ps):
        return PAPER_P, []
    return ps[0], [f"the run has no p = {fmt_p(PAPER_P)}; showing p = {fmt_p(ps[0])}"]


def fig1_training(train: pd.DataFrame) -> Built:
    """Build Fig. 1 from training rows joined with their cell config (reports.store)."""
    notes: list[str] = []
    p, pnote = _pick_p(train)
    notes += pnote
    at_p = select(train, loss_p=p) if p is not None else train.iloc[0:0]
    ab_ns = set(select(at_p, "hierarchical")["n_robots"]) | set(select(at_p, "decentralized")["n_robots"])
    a_ns, a_missing = choose(PAPER_A_N, ab_ns, 3)
    b_ns, b_missing = choose(PAPER_B_N, set(select(at_p, "hierarchical")["n_robots"]), 3, largest=True)
    ptxt = fmt_p(p) if p is not None else fmt_p(PAPER_P)
    if a_missing:
        notes.append(f"(a) the run has no training data for N = {fmt_list(a_missing)} at p = {ptxt}")
    if b_missing:
        notes.append(f"(b) the run has no hierarchical training data for N = {fmt_list(b_missing)} at p = {ptxt}")

    with paper_style():
        fig = new_figure(3.7)
        ncol = max(len(a_ns), 1)
        top, bottom = fig.subfigures(2, 1, height_ratios=[1.0, 1.1])
        axes_a = list(top.subplots(1, ncol, sharey=True, squeeze=False)[0])
        ax_b = bottom.subplots()
        handles: dict[str, object] = {}
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
                _draw(ax, c, method_color(method), method_label(method))
                drawn = True
            if not drawn:
                placeholder(ax, "no data")
            ax.set_title(f"N = {n}")
            ax.xaxis.set_major_locator(MaxNLocator(nbins=3, steps=[1, 2, 5, 10], integer=True))
            ax.xaxis.set_major_formatter(FuncFormatter(thousands))
            if k > 0:
                ax.tick_params(labelleft=False)
            for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
                handles.setdefault(lab, h)
        axes_a[0].set_ylabel("episode reward")
        top.supxlabel("training episode", fontsize=FONT_PT)
        if handles:
            order = sorted(handles, key=label_order)
            top.legend([handles[k] for k in order], order, loc="outside upper center",
                       ncol=len(handles), frameon=False, handlelength=1.5, columnspacing=1.0)
        axes_a[0].annotate("(a)", (0.0, 1.0), xycoords="axes fraction", xytext=(-18, 4),
                           textcoords="offset points", fontweight="bold", va="bottom")

        colors = n_palette([int(n) for n in b_ns])
        drawn_b = False
        for n in b_ns:
            c = training_curve(at_p, "hierarchical", int(n), p)
            if c is not None:
                _draw(ax_b, c, colors[int(n)], f"N = {int(n)}")
                drawn_b = True
        if drawn_b:
            ax_b.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False,
                        title="Hierarchical\n(ours)", handlelength=1.2, borderaxespad=0.2)
            ax_b.xaxis.set_major_formatter(FuncFormatter(thousands))
            ax_b.xaxis.set_major_locator(MaxNLocator(nbins=5, steps=[1, 2, 5, 10], integer=True))
        else:
            placeholder(ax_b, f"no hierarchical training data at p = {ptxt}")
        ax_b.set_xlabel("training episode")
        ax_b.set_ylabel("episode reward")
        ax_b.annotate("(b)", (0.0, 1.0), xycoords="axes fraction", xytext=(-18, 4),
                      textcoords="offset points", fontweight="bold", va="bottom")
    return Built(fig, notes)
