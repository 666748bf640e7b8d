"""Shared look of the report figures: paper-column size, fonts, colours, placeholders.

Figures are built as ``matplotlib.figure.Figure`` objects without pyplot (no global
state, no GUI backend; rendering uses Agg), styled with seaborn, sized for a paper column
(3.5 in wide) with 7 pt text. Builders return a ``Built`` (the figure plus notes that the
index prints under it, e.g. which of the paper's configurations the run lacks) and a
caption (configuration, seeds, episodes, smoothing, what the band is) that the index shows
under the figure and ``reports.writers.save_figure`` stores as PDF metadata and a sidecar
``.txt``. One colour, line style and legend rank per method from the report's method table
(``reports.figures.styles``), and one label, the method's own (``Method.label()``), in
every figure: "Hierarchical (ours)" is blue everywhere; several team sizes of one method are
shades of that method's colour (``shades``), never another palette.
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Literal

import matplotlib
import numpy as np
import seaborn as sns
from matplotlib.axes import Axes
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure
from matplotlib.legend import Legend
from matplotlib.typing import RcKeyType

from algorithms.base import UNRANKED
from algorithms.registry import available, find_method
from reports.figures.styles import method_style_of

COLUMN_IN = 3.5  # paper column width, inches
FONT_PT = 7
DPI = 200
RC: dict[RcKeyType, Any] = {
    "font.size": FONT_PT, "axes.labelsize": FONT_PT, "axes.titlesize": FONT_PT,
    "xtick.labelsize": FONT_PT, "ytick.labelsize": FONT_PT, "legend.fontsize": FONT_PT,
    "legend.title_fontsize": FONT_PT, "lines.linewidth": 1.0, "lines.markersize": 3.5,
    "axes.linewidth": 0.6, "grid.linewidth": 0.4, "xtick.major.pad": 1.5,
    "ytick.major.pad": 1.5, "axes.labelpad": 2.0, "axes.titlepad": 3.0,
    "pdf.fonttype": 42, "svg.fonttype": "none",
}


@dataclass
class Built:
    """A built figure and the notes printed with it in the index."""

    fig: Figure
    notes: list[str] = field(default_factory=list)
    caption: str = ""


@contextmanager
def paper_style() -> Iterator[None]:
    """Seaborn ``whitegrid`` with the paper-column font sizes, for building one figure."""
    with sns.axes_style("whitegrid"), matplotlib.rc_context(RC):
        yield


def new_figure(height_in: float, width_in: float = COLUMN_IN) -> Figure:
    return Figure(figsize=(width_in, height_in), layout="constrained", dpi=DPI)


def method_color(method: str) -> tuple[float, float, float]:
    """The method's colour in the report's method table (``reports.figures.styles``)."""
    return to_rgb(method_style_of(method).color)


def method_style(method: str) -> str:
    """The method's line style in the report's method table."""
    return method_style_of(method).line_style


def method_label(method: str) -> str:
    """The label a method declares (``Method.label()``), else its name."""
    cls = find_method(method)
    return cls.label() if cls is not None else method


def label_order(label: str) -> int:
    """Legend and table position of a method label: the rank in the report's method table of
    the registered method with that label (the paper's method first, then the baselines),
    others last."""
    return _ranks().get(label, UNRANKED)



def ranked_legend(axes: Iterable[Axes]) -> tuple[list[Any], list[str]]:
    """(handles, labels) of every labelled artist of ``axes``, each label once (its first
    handle), in ``label_order`` (ties: first appearance)."""
    handles: dict[str, Any] = {}
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(lab, h)
    labels = sorted(handles, key=label_order)
    return [handles[lab] for lab in labels], labels

def fitted_legend(fig: Figure, handles: Sequence[Any], labels: Sequence[str],
                  loc: Literal["outside lower center", "outside upper center"],
                  max_cols: int = 4, **kwargs: Any) -> Legend:
    """``fig.legend`` in at most ``max_cols`` columns, fewer when a row of entries would be
    wider than the figure: a legend wider than its figure is cut at the image's edges (the
    smoke report's success_vs_n showed "PI" of PIBT). A legend that fits keeps its columns,
    so a figure that was not clipped is drawn as before."""
    for ncol in range(min(len(labels), max_cols), 0, -1):
        legend = fig.legend(handles, labels, loc=loc, ncol=ncol, frameon=False, **kwargs)
        if ncol == 1 or legend.get_window_extent().width <= fig.bbox.width:
            return legend
        legend.remove()
    raise ValueError("fitted_legend needs at least one label")


@lru_cache(maxsize=1)
def _ranks() -> dict[str, int]:
    ranks: dict[str, int] = {}
    for name in available():
        cls = find_method(name)
        if cls is not None:
            ranks.setdefault(cls.label(), method_style_of(name).rank)
    return ranks


def shades(method: str, ns: Sequence[int], spread: float = 0.35) -> dict[int, tuple[float, float, float]]:
    """One shade of ``method``'s colour per team size, dark (small N) to light (large N),
    so a panel of one method keeps that method's hue; ``spread`` (0..1) is how far the
    ends go toward black and white."""
    base = np.asarray(method_color(method), dtype=np.float64)
    mix = np.linspace(-spread, spread, len(ns)) if len(ns) > 1 else np.zeros(1)
    out: dict[int, tuple[float, float, float]] = {}
    for m, n in zip(mix, sorted(ns), strict=True):  # < 0 darkens toward black, > 0 lightens toward white
        c = base * (1 + m) if m < 0 else base + (1 - base) * m
        r, g, b = (float(x) for x in np.clip(c, 0, 1))
        out[int(n)] = (r, g, b)
    return out


def placeholder(ax: Axes, text: str) -> None:
    """Mark a panel that has no data, so it is never silently empty."""
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes,
            fontsize=FONT_PT, color="0.35", wrap=True)
    ax.set_xticks([])
    ax.set_yticks([])


def choose(paper: Iterable[float], present: Iterable[float], k: int,
           largest: bool = False) -> tuple[list[float], list[float]]:
    """Values to plot and the paper's values missing from the run.

    The paper's values present in the run; if none is, up to ``k`` of the run's own values
    (smallest, or largest with ``largest``), so a smoke run still gives a figure.
    """
    pres = sorted({float(v) for v in present})
    pap = [float(v) for v in paper]
    chosen = [v for v in pap if any(np.isclose(v, q) for q in pres)]
    missing = [v for v in pap if not any(np.isclose(v, q) for q in pres)]
    if not chosen:
        chosen = pres[-k:] if largest else pres[:k]
    return chosen, missing


def fmt_list(values: Iterable[float]) -> str:
    return ", ".join(f"{v:g}" for v in values)


def thousands(x: float, _pos: int | None = None) -> str:
    """Tick formatter: 1500 -> '1.5k', 150 -> '150' (exact, so two ticks never share a label)."""
    return f"{x / 1000:g}k" if abs(x) >= 1000 else f"{x:g}"
