"""Learning curves of every learned method of a run: the generic report's training section.

One panel per configuration (team size N x loss probability p) the run trained; in each,
every learned method's smoothed team return (eq:reward summed over an episode) against the
training episode: the mean over seeds and, with several seeds, a pointwise 95% Student t
band over seeds. Any method that wrote training rows is drawn, by the label, colour and line
style the report's method table gives it, so a plugin's curve shows whether it learned.
``training_curve`` and ``draw_curve`` are shared with the paper's Fig. 1.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from matplotlib.axes import Axes

from reports.data.store import fmt_p, select
from reports.figures.plotting import (
    Built,
    fitted_legend,
    label_order,
    method_color,
    method_label,
    method_style,
    new_figure,
    paper_style,
    placeholder,
    ranked_legend,
    thousands,
)
from reports.stats import smooth, smoothing_window, t_band

__all__ = ["Curve", "draw_curve", "learning_curves", "smoothing_text", "training_curve"]


@dataclass(frozen=True)
class Curve:
    """A smoothed training curve: episodes (T,), mean/lo/hi (T,) over ``seeds`` runs."""

    episode: np.ndarray
    mean: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    seeds: int
    window: int


def training_curve(train: pd.DataFrame, method: str, n: int, p: float | None,
                   metric: str = "team_return") -> Curve | None:
    """Smoothed ``metric`` per episode for one (method, N, p), over the cells (seeds) present
    (p None: every p, as in ``select``)."""
    rows = select(train, method, n, p)
    if rows.empty:
        return None
    wide = rows.pivot_table(index="episode", columns="cell_id", values=metric, aggfunc="mean")
    wide = wide.sort_index()
    window = smoothing_window(len(wide))
    curves = np.stack([smooth(wide[c].to_numpy(), window) for c in wide.columns])  # (S, T)
    curves[np.isnan(wide.to_numpy().T)] = np.nan  # keep gaps of shorter runs as gaps
    mean, lo, hi = t_band(curves)
    return Curve(wide.index.to_numpy(), mean, lo, hi, curves.shape[0], window)


def draw_curve(ax: Axes, curve: Curve, color: tuple[float, float, float], label: str, ls: str = "-",
          band_alpha: float = 0.25) -> None:
    """Mean line in ``ls``; with several seeds the band, its edges thin lines in the same
    colour and style, so overlapping bands stay apart."""
    ax.plot(curve.episode, curve.mean, color=color, label=label, ls=ls, lw=1.3)
    if curve.seeds > 1:
        ax.fill_between(curve.episode, curve.lo, curve.hi, color=color, alpha=band_alpha, lw=0)
        for edge in (curve.lo, curve.hi):
            ax.plot(curve.episode, edge, color=color, ls=ls, lw=0.4, alpha=0.8, label="_band edge")



def smoothing_text(windows: list[int]) -> str:
    """How the curves were smoothed, for a caption."""
    if windows == [1]:
        return "not smoothed (5% of training is under 2 episodes)"
    return (f"trailing moving average over {'/'.join(map(str, windows))} episodes (5% of training)")


def learned_configurations(train: pd.DataFrame) -> list[tuple[int, float]]:
    """(N, p) of every configuration with training rows, sorted."""
    if train.empty:
        return []
    pairs = train[["n_robots", "loss_p"]].drop_duplicates()
    return sorted((int(n), float(p)) for n, p in pairs.itertuples(index=False))


def learning_curves(train: pd.DataFrame) -> Built:
    """Every learned method's training curve, one panel per configuration (rows: p, columns: N)."""
    from matplotlib.ticker import FuncFormatter, MaxNLocator

    configs = learned_configurations(train)
    methods = sorted(dict.fromkeys(map(str, train["method"])) if len(train) else [],
                     key=lambda m: (label_order(method_label(m)), m))
    ns = sorted({n for n, _ in configs})
    ps = sorted({p for _, p in configs})
    drawn: list[Curve] = []
    with paper_style():
        ncol, nrow = max(len(ns), 1), max(len(ps), 1)
        fig = new_figure(1.6 * nrow + 0.5, width_in=max(3.4, 1.7 * ncol))
        axes = fig.subplots(nrow, ncol, squeeze=False)
        for i, p in enumerate(ps):
            for j, n in enumerate(ns):
                ax: Axes = axes[i][j]
                ax.set_title(f"N = {n}, p = {fmt_p(p)}")
                if (n, p) not in configs:
                    placeholder(ax, "not trained\nin this run")
                    continue
                for method in methods:
                    c = training_curve(train, method, n, p)
                    if c is not None:
                        draw_curve(ax, c, method_color(method), method_label(method), method_style(method))
                        drawn.append(c)
                ax.xaxis.set_major_locator(MaxNLocator(nbins=3, steps=[1, 2, 5, 10], integer=True))
                ax.xaxis.set_major_formatter(FuncFormatter(thousands))
                ax.yaxis.set_major_locator(MaxNLocator(nbins=4))
            axes[i][0].set_ylabel("team return")
        if not configs:
            placeholder(axes[0][0], "the run has no training rows\n(no learned method)")
        else:
            fig.supxlabel("training episode")
        handles, labels = ranked_legend([a for row in axes for a in row])
        if handles:
            fitted_legend(fig, handles, labels, "outside upper center", handlelength=2.5)
    return Built(fig, [], _caption(drawn, methods, len(configs)))


def _caption(drawn: list[Curve], methods: list[str], configs: int) -> str:
    if not drawn:
        return "Learning curves: the run has no training rows (no learned method, or none done)."
    seeds = sorted({c.seeds for c in drawn})
    band = ("shaded band: pointwise 95% Student t interval over seeds of the mean curve"
            if max(seeds) > 1 else "no band (one seed per configuration)")
    return (f"Learning curves of every learned method of the run ({', '.join(method_label(m) for m in methods)}) "
            f"at each of its {configs} trained configurations (N x p). Team return per training episode, "
            f"{smoothing_text(sorted({c.window for c in drawn}))}; line: mean over "
            f"{'/'.join(map(str, seeds))} seeds; {band}.")
