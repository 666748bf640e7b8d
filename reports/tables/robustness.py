"""Robustness of training, per learned method and team size: how often a seed collapsed
and how often a training run's return fell.

Two shares per (method, N), each over that method's seeds at every p of the run:

* **collapsed**: seeds whose success rate (mean over evaluation episodes, in the first
  execution mode of the run's order: argmax when it ran) is below ``COLLAPSE`` (10%);
* **falling**: seeds whose team return fell during training, i.e. the mean of the last
  window of the curve is below the mean of the first (``reports.stats.curve_shape``: the
  first and last 20% of the episodes); seeds too short for two windows are not counted.

A method with no training rows (a planner) is left out: it has no training to be robust in.
"""
from __future__ import annotations

import pandas as pd

from reports.data.store import execution_order
from reports.figures.plotting import label_order, method_label
from reports.stats import curve_shape

__all__ = ["COLLAPSE", "ROBUSTNESS_CAPTION", "robustness_display", "robustness_frame", "robustness_markdown"]

COLLAPSE = 0.10  # a seed below this success rate counts as collapsed
ROBUSTNESS_CAPTION = (f"Robustness of training per learned method and team size N (over its seeds at every p): "
                      f"collapsed = seeds whose success rate, in the first execution mode, is below "
                      f"{COLLAPSE:.0%}; falling = seeds whose team return over the last 20% of training "
                      "episodes is below that over the first 20% (seeds with fewer than 50 episodes not counted).")
COLUMNS = ["method", "label", "n_robots", "seeds", "collapsed", "collapsed_share", "curves", "falling",
           "falling_share"]


def _falling(train: pd.DataFrame) -> dict[str, bool]:
    """cell_id -> whether its return fell (None-shaped curves left out)."""
    out: dict[str, bool] = {}
    for cid, g in train.groupby("cell_id", sort=True):
        shape = curve_shape(g.sort_values("episode")["team_return"].to_numpy())
        if shape is not None:
            out[str(cid)] = shape.gain < 0
    return out


def robustness_frame(train: pd.DataFrame, evals: pd.DataFrame) -> pd.DataFrame:
    """One row per learned method and N: seeds, collapsed seeds, seeds with a curve, falling ones."""
    if train.empty:
        return pd.DataFrame(columns=COLUMNS)
    learned = set(map(str, train["method"]))
    mode = next(iter(execution_order(evals["execution"])), None) if len(evals) else None
    ev = evals[evals["method"].isin(learned) & (evals["execution"] == mode)] if mode is not None else evals.iloc[0:0]
    success = ev.groupby(["method", "n_robots", "cell_id"])["success_rate"].mean()
    falling = _falling(train)
    cells = train[["method", "n_robots", "cell_id"]].drop_duplicates()
    rows = []
    for (method, n), g in cells.groupby(["method", "n_robots"], sort=True):
        ids = list(map(str, g["cell_id"]))
        rates = [float(success[(method, n, c)]) for c in ids if (method, n, c) in success.index]
        falls = [falling[c] for c in ids if c in falling]
        collapsed = sum(r < COLLAPSE for r in rates)
        rows.append({"method": str(method), "label": method_label(str(method)), "n_robots": int(n),
                     "seeds": len(rates), "collapsed": collapsed,
                     "collapsed_share": collapsed / len(rates) if rates else float("nan"),
                     "curves": len(falls), "falling": int(sum(falls)),
                     "falling_share": sum(falls) / len(falls) if falls else float("nan")})
    out = pd.DataFrame(rows, columns=COLUMNS)
    order = out["label"].map(label_order)
    return out.assign(_o=order).sort_values(["_o", "label", "n_robots"], kind="stable").drop(columns="_o")


def _share(k: int, n: int) -> str:
    return "—" if n == 0 else f"{k}/{n} ({k / n:.0%})"


def robustness_display(frame: pd.DataFrame) -> pd.DataFrame:
    """The table as the index shows it: method, N, collapsed k/n (share), falling k/n (share)."""
    return pd.DataFrame({"method": frame["label"], "N": frame["n_robots"].astype(str),
                         "collapsed seeds": [_share(r.collapsed, r.seeds) for r in frame.itertuples()],
                         "falling returns": [_share(r.falling, r.curves) for r in frame.itertuples()]})


def robustness_markdown(frame: pd.DataFrame) -> str:
    """``robustness.md``: the caption and the table."""
    lines = ["# Robustness of training", "", ROBUSTNESS_CAPTION, ""]
    if frame.empty:
        return "\n".join(lines + ["The run has no training rows (no learned method, or none done)."]) + "\n"
    shown = robustness_display(frame)
    lines += ["| " + " | ".join(shown.columns) + " |", "|" + "---|" * len(shown.columns)]
    lines += ["| " + " | ".join(map(str, r)) + " |" for r in shown.itertuples(index=False)]
    return "\n".join(lines) + "\n"
