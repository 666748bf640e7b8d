"""Robustness of training: how often a seed collapsed and how often a training run's
return fell, per learned method, variant and team size; and every seed's outcome.

``robustness_frame``: two shares per (method, variant, N), each over that variant's seeds
at every p of the run:

* **collapsed**: seeds whose success rate (mean over evaluation episodes, in the first
  execution mode of the run's order: argmax when it ran) is below ``COLLAPSE`` (10%);
* **falling**: seeds whose team return fell during training, i.e. the mean of the last
  window of the curve is below the mean of the first (``reports.stats.curve_shape``: the
  first and last 20% of the episodes); seeds too short for two windows are not counted.

``seeds_frame``: one row per (method, variant, N, p, execution mode) with each seed's
success rate, their mean, standard deviation and minimum, and the same two counts, so a
reader sees whether a mean is a typical seed or a mixture of learned and collapsed ones.

Variants (``reports.data.variants``: the ablation's arms, or ``protocol = "mappo"`` cells
beside ``--against``'s paper-protocol cells) are never pooled. A method with no training
rows (a planner) is left out: it has no training to be robust in.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from reports.data.store import execution_order, fmt_p
from reports.data.variants import variant_suffix
from reports.figures.plotting import label_order, method_label
from reports.stats import curve_shape

__all__ = ["COLLAPSE", "ROBUSTNESS_CAPTION", "SEEDS_CAPTION", "robustness_display", "robustness_frame",
           "robustness_markdown", "seeds_frame", "seeds_markdown"]

COLLAPSE = 0.10  # a seed below this success rate counts as collapsed
ROBUSTNESS_CAPTION = (f"Robustness of training per learned method (and variant) and team size N (over its seeds "
                      f"at every p): collapsed = seeds whose success rate, in the first execution mode, is below "
                      f"{COLLAPSE:.0%}; falling = seeds whose team return over the last 20% of training "
                      "episodes is below that over the first 20% (seeds with fewer than 50 episodes not counted).")
SEEDS_CAPTION = ("Every seed of every learned configuration: success rate per seed (mean over its evaluation "
                 "episodes, in seed order), their mean, standard deviation over seeds (percentage points) and "
                 f"minimum; collapsed = seeds below {COLLAPSE:.0%}; falling = seeds whose team return over the "
                 "last 20% of training episodes is below that over the first 20%.")
COLUMNS = ["method", "label", "n_robots", "seeds", "collapsed", "collapsed_share", "curves", "falling",
           "falling_share"]
SEED_COLUMNS = ["method", "label", "n_robots", "loss_p", "execution", "seeds", "success_by_seed", "mean", "sd_pp",
                "min", "collapsed", "curves", "falling"]


def _falling(train: pd.DataFrame) -> dict[str, bool]:
    """cell_id -> whether its return fell (None-shaped curves left out)."""
    out: dict[str, bool] = {}
    for cid, g in train.groupby("cell_id", sort=True):
        shape = curve_shape(g.sort_values("episode")["team_return"].to_numpy())
        if shape is not None:
            out[str(cid)] = shape.gain < 0
    return out


def _labels(cells: pd.DataFrame, variants: pd.Series | None) -> pd.DataFrame:
    """The learned cells (method, n_robots, cell_id, seed, loss_p) with their display label:
    the method's, with the variant's suffix."""
    out = cells.copy()
    var = out["cell_id"].map(variants).fillna("") if variants is not None else pd.Series("", index=out.index)
    out["label"] = [method_label(str(m)) + variant_suffix(str(v)) for m, v in zip(out["method"], var, strict=True)]
    return out


def _ordered(frame: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    order = frame["label"].map(lambda s: label_order(s.split(" [", 1)[0]))
    return frame.assign(_o=order).sort_values(["_o", "label", *keys], kind="stable").drop(columns="_o")


def robustness_frame(train: pd.DataFrame, evals: pd.DataFrame, variants: pd.Series | None = None) -> pd.DataFrame:
    """One row per learned method, variant and N: seeds, collapsed seeds, seeds with a
    curve, falling ones. ``variants``: cell_id -> variant label (``cell_variants``)."""
    if train.empty:
        return pd.DataFrame(columns=COLUMNS)
    learned = set(map(str, train["method"]))
    mode = next(iter(execution_order(evals["execution"])), None) if len(evals) else None
    ev = evals[evals["method"].isin(learned) & (evals["execution"] == mode)] if mode is not None else evals.iloc[0:0]
    success = ev.groupby("cell_id")["success_rate"].mean()
    falling = _falling(train)
    cells = _labels(train[["method", "n_robots", "cell_id"]].drop_duplicates(), variants)
    rows = []
    for (method, label, n), g in cells.groupby(["method", "label", "n_robots"], sort=True):
        ids = list(map(str, g["cell_id"]))
        rates = [float(success[c]) for c in ids if c in success.index]
        falls = [falling[c] for c in ids if c in falling]
        collapsed = sum(r < COLLAPSE for r in rates)
        rows.append({"method": str(method), "label": str(label), "n_robots": int(n),
                     "seeds": len(rates), "collapsed": collapsed,
                     "collapsed_share": collapsed / len(rates) if rates else float("nan"),
                     "curves": len(falls), "falling": int(sum(falls)),
                     "falling_share": sum(falls) / len(falls) if falls else float("nan")})
    return _ordered(pd.DataFrame(rows, columns=COLUMNS), ["n_robots"])


def seeds_frame(train: pd.DataFrame, evals: pd.DataFrame, variants: pd.Series | None = None) -> pd.DataFrame:
    """One row per learned method, variant, N, p and execution mode: each seed's success
    rate (seed order) and their summary (module doc)."""
    if train.empty or evals.empty:
        return pd.DataFrame(columns=SEED_COLUMNS)
    learned = set(map(str, train["method"]))
    ev = evals[evals["method"].isin(learned)]
    per_cell = ev.groupby(["cell_id", "execution"])["success_rate"].mean()
    falling = _falling(train)
    cells = _labels(ev[["method", "n_robots", "loss_p", "seed", "cell_id"]].drop_duplicates("cell_id"), variants)
    rows = []
    for (method, label, n, p), g in cells.groupby(["method", "label", "n_robots", "loss_p"], sort=True):
        g = g.sort_values("seed")
        falls = [falling[c] for c in map(str, g["cell_id"]) if c in falling]
        modes = set(per_cell[per_cell.index.get_level_values("cell_id").isin(g["cell_id"])].index
                    .get_level_values("execution"))
        for mode in execution_order(modes):
            rates = np.array([per_cell[(c, mode)] for c in g["cell_id"] if (c, mode) in per_cell.index])
            rows.append({"method": str(method), "label": str(label), "n_robots": int(n), "loss_p": float(p),
                         "execution": mode, "seeds": len(rates),
                         "success_by_seed": ", ".join(f"{r:.1%}" for r in rates),
                         "mean": float(rates.mean()), "sd_pp": float(100 * rates.std(ddof=1)) if len(rates) > 1
                         else float("nan"), "min": float(rates.min()), "collapsed": int((rates < COLLAPSE).sum()),
                         "curves": len(falls), "falling": int(sum(falls))})
    return _ordered(pd.DataFrame(rows, columns=SEED_COLUMNS), ["n_robots", "loss_p"])


def _share(k: int, n: int) -> str:
    return "—" if n == 0 else f"{k}/{n} ({k / n:.0%})"


def robustness_display(frame: pd.DataFrame) -> pd.DataFrame:
    """The table as the index shows it: method, N, collapsed k/n (share), falling k/n (share)."""
    return pd.DataFrame({"method": frame["label"], "N": frame["n_robots"].astype(str),
                         "collapsed seeds": [_share(r.collapsed, r.seeds) for r in frame.itertuples()],
                         "falling returns": [_share(r.falling, r.curves) for r in frame.itertuples()]})


def _table(shown: pd.DataFrame) -> list[str]:
    return ["| " + " | ".join(shown.columns) + " |", "|" + "---|" * len(shown.columns),
            *("| " + " | ".join(map(str, r)) + " |" for r in shown.itertuples(index=False))]


def robustness_markdown(frame: pd.DataFrame) -> str:
    """``robustness.md``: the caption and the table."""
    lines = ["# Robustness of training", "", ROBUSTNESS_CAPTION, ""]
    if frame.empty:
        return "\n".join(lines + ["The run has no training rows (no learned method, or none done)."]) + "\n"
    return "\n".join(lines + _table(robustness_display(frame))) + "\n"


def seeds_markdown(frame: pd.DataFrame) -> str:
    """``seeds.md``: the caption and one row per configuration and mode."""
    lines = ["# Every seed", "", SEEDS_CAPTION, ""]
    if frame.empty:
        return "\n".join(lines + ["The run has no evaluated learned cell."]) + "\n"
    shown = pd.DataFrame({
        "method": frame["label"], "N": frame["n_robots"].astype(str), "p": frame["loss_p"].map(fmt_p),
        "mode": frame["execution"], "success per seed": frame["success_by_seed"],
        "mean": frame["mean"].map(lambda v: f"{v:.1%}"),
        "SD (pp)": frame["sd_pp"].map(lambda v: "—" if v != v else f"{v:.1f}"),
        "min": frame["min"].map(lambda v: f"{v:.1%}"),
        "collapsed": [f"{r.collapsed}/{r.seeds}" for r in frame.itertuples()],
        "falling": [f"{r.falling}/{r.curves}" if r.curves else "—" for r in frame.itertuples()]})
    return "\n".join(lines + _table(shown)) + "\n"
