"""Training diagnostics per update (docs/decisions/0200): what moved in training.

One panel per diagnostic the train rows carry (``diag_*`` columns and the collision rate):
policy entropy (solid: the robot-level control policy; dashed: the hierarchical reference),
KL across each update, the policy's gradient norm before clipping, the critic's explained
variance, the mean raw advantage G - V, the share of Wait and the collision rate; one line
per method, the mean over its cells per training episode, smoothed by a trailing moving
average. Drawn only for runs whose train rows hold the diagnostics (stores written before
them read them as NaN): ``training_diagnostics`` returns None otherwise, so older reports
do not change.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from reports.figures.plotting import Built, method_color, method_label, new_figure, paper_style, ranked_legend
from reports.stats import smooth, smoothing_window

PANELS = (  # (column, y label, dashed companion column)
    ("diag_entropy", "entropy (nats)", "diag_entropy_ref"),
    ("diag_kl", "KL per update", "diag_kl_ref"),
    ("diag_grad_norm", "grad norm", None),
    ("diag_explained_variance", "critic expl. var.", None),
    ("diag_adv_mean", "mean advantage G - V", None),
    ("diag_wait_share", "share of Wait", None),
    ("collision_rate", "collision rate", None),
)


def has_diagnostics(train: pd.DataFrame) -> bool:
    """Whether any train row carries the diagnostics."""
    return "diag_entropy" in train.columns and bool(train["diag_entropy"].notna().any())


def _curve(rows: pd.DataFrame, column: str) -> tuple[np.ndarray, np.ndarray] | None:
    per_episode = rows.groupby("episode")[column].mean().dropna()
    if per_episode.empty:
        return None
    values = per_episode.to_numpy(dtype=float)
    return per_episode.index.to_numpy(), smooth(values, smoothing_window(len(values)))


def training_diagnostics(train: pd.DataFrame) -> Built | None:
    """The diagnostics figure of a run's train rows, or None when they hold none."""
    if not has_diagnostics(train):
        return None
    methods = [m for m in dict.fromkeys(train["method"])
               if train.loc[train["method"] == m, "diag_entropy"].notna().any()]
    with paper_style():
        fig = new_figure(7.0, 7.0)
        axes = fig.subplots(4, 2).ravel()
        for ax, (column, label, companion) in zip(axes, PANELS, strict=False):
            for method in methods:
                rows = train[train["method"] == method]
                for col, style in ((column, "-"), (companion, "--")):
                    curve = _curve(rows, col) if col is not None else None
                    if curve is not None:
                        ax.plot(*curve, style, color=method_color(method), lw=1.0,
                                label=method_label(method) if style == "-" else None)
            ax.set_ylabel(label)
            ax.set_xlabel("training episode")
        axes[-1].axis("off")
        handles, labels = ranked_legend(axes[:-1])
        axes[-1].legend(handles, labels, loc="center", frameon=False)
    caption = ("Training diagnostics per update (mean over each method's cells per episode, trailing moving "
               "average): entropy (dashed: hierarchical reference), KL across each update (dashed: reference), "
               "policy gradient norm before clipping, critic explained variance, mean raw advantage, share of "
               "Wait, collision rate.")
    return Built(fig, [f"methods: {', '.join(methods)}"], caption)
