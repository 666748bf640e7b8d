"""One y-scale for a row of panels only where their ranges agree.

A shared y-axis lets the widest panel set every panel's scale: in Fig. 1(a) the
decentralized N = 60 band (down to about -290) squashed N = 20 and 40 into a few pixels.
``fit_ylims`` keeps each panel's own autoscaled limits when their spans differ by more
than ``ratio`` and gives the row their union otherwise (then the panels compare by eye).
"""
from __future__ import annotations

from collections.abc import Sequence

from matplotlib.axes import Axes

SPAN_RATIO = 1.5  # widest / narrowest span above which panels keep their own y-scale


def spans_differ(limits: Sequence[tuple[float, float]], ratio: float = SPAN_RATIO) -> bool:
    """True when the widest (hi - lo) of ``limits`` exceeds ``ratio`` times the narrowest."""
    spans = [hi - lo for lo, hi in limits if hi > lo]
    return bool(spans) and max(spans) > ratio * min(spans)


def fit_ylims(axes: Sequence[Axes], ratio: float = SPAN_RATIO) -> bool:
    """Give ``axes`` (panels with data, already autoscaled) one y-range unless their spans
    differ (``spans_differ``); returns True when each keeps its own scale."""
    axes = list(axes)
    if len(axes) < 2:
        return len(axes) == 1
    limits = [ax.get_ylim() for ax in axes]
    if spans_differ(limits, ratio):
        return True
    lo, hi = min(lo for lo, _ in limits), max(hi for _, hi in limits)
    for ax in axes:
        ax.set_ylim(lo, hi)
    return False
