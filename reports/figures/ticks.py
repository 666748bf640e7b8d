"""Tick labels that never collide, and log axes with enough labelled ticks.

Fig. 3 puts a tick on every measured team size; at N = 80, 90, 100 on a half-column panel
the labels ran into each other. ``spaced_formatter`` labels a tick only when it lies at
least ``min_frac`` of the axis range from the last labelled one (the tick itself stays).
Fig. 3(a)'s log axis had two labels (1000, 10000) over 2.6 decades; ``log_ticks`` labels
1-2-5 steps (200, 500, 1k, 2k, ...) when the axis spans few decades.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.ticker import FixedFormatter, FuncFormatter, LogLocator, NullFormatter

from reports.figures.plotting import thousands


def spaced_labels(values: Sequence[float], min_frac: float, span: float | None = None) -> list[str]:
    """Label of each of ``values`` (ascending): the number, or "" when it lies closer than
    ``min_frac`` x ``span`` (default: the values' range) to the previous labelled value.
    The first and the last value are always labelled (the last one bumps its neighbour)."""
    vals = [float(v) for v in values]
    if not vals:
        return []
    span = span if span is not None else (max(vals) - min(vals)) or 1.0
    gap = min_frac * span
    keep = [False] * len(vals)
    keep[-1] = True
    last = vals[-1]
    for i in range(len(vals) - 2, -1, -1):  # from the right, so the largest N is labelled
        if last - vals[i] >= gap or i == 0:
            keep[i] = True
            last = vals[i]
    if len(vals) > 1 and keep[1] and vals[1] - vals[0] < gap:
        keep[1] = False  # the first label wins against its right neighbour
    return [f"{v:g}" if k else "" for v, k in zip(vals, keep, strict=True)]


def spaced_formatter(ax: Axes, values: Sequence[float], min_frac: float) -> None:
    """Fixed x ticks at ``values`` with ``spaced_labels`` over the axis' current x range."""
    lo, hi = ax.get_xlim()
    ax.set_xticks(list(values))
    ax.xaxis.set_major_formatter(FixedFormatter(spaced_labels(values, min_frac, span=abs(hi - lo))))


def log_ticks(ax: Axes, max_decades_for_125: float = 3.0) -> None:
    """Major ticks of a log y axis at 1-2-5 steps when it spans at most
    ``max_decades_for_125`` decades, else at powers of ten; labels as 200, 1k, 20k."""
    lo, hi = ax.get_ylim()
    decades = float(np.log10(hi / lo)) if lo > 0 and hi > lo else 0.0
    subs = (1.0, 2.0, 5.0) if decades <= max_decades_for_125 else (1.0,)
    ax.yaxis.set_major_locator(LogLocator(base=10, subs=subs))
    ax.yaxis.set_major_formatter(FuncFormatter(thousands))
    ax.yaxis.set_minor_formatter(NullFormatter())
