"""Robustness of training: how often a seed collapsed and how often a training run's
return fell, per learned method, variant and team size; and every seed's outcome.

``robustness_frame``: two shares per (method, variant, N), each over that variant's seeds
at every p of the run:

* **collapsed**: seeds whose success rate (mean over evaluation episodes, in sample
  execution, the policy as it was trained; in the first execution mode of the run's order
  where the run has no sample evaluation) is below ``COLLAPSE`` (10%); argmax execution can
  livelock a policy that trained well (the hierarchical method's joint-Wait fallback), which
  is an execution result, shown per mode in ``seeds_frame``, not a training collapse
  (docs/decisions/0244); a
  lifelong cell's success is near 0 by construction, so a lifelong seed counts as collapsed
  where its throughput is below ``COLLAPSE`` of the best mean throughput over seeds of any
  method (planners included, any mode) at its configuration (N, p) (docs/decisions/0238);
* **falling**: seeds whose team return fell during training, i.e. the mean of the last
  window of the curve is below the mean of the first (``reports.stats.curve_shape``: the
  first and last 20% of the episodes); seeds too short for two windows are not counted.

``seeds_frame``: one row per (method, variant, N, p, execution mode) with each seed's
success rate (throughput, goals per step, for a lifelong cell: a ``task`` column then
says which), their mean, standard deviation and minimum, and the same two counts, so a
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
from reports.tables.mapf import with_score

__all__ = ["COLLAPSE", "ROBUSTNESS_CAPTION", "collapse_mode", "SEEDS_CAPTION", "robustness_display", "robustness_frame",
           "robustness_markdown", "seeds_frame", "seeds_markdown"]

COLLAPSE = 0.10  # a seed below this success rate counts as collapsed
LIFELONG_COLLAPSE = (f"A lifelong seed (success near 0 by construction) counts as collapsed where its throughput "
                     f"is below {COLLAPSE:.0%} of the best mean throughput of any method (planners included) at "
                     "its configuration (docs/decisions/0238).")
ROBUSTNESS_CAPTION = (f"Robustness of training per learned method (and variant) and team size N (over its seeds "
                      f"at every p): collapsed = seeds whose success rate in sample execution (the policy as "
                      f"trained; argmax can livelock a policy that trained well, see seeds.md for every mode) is "
                      f"below {COLLAPSE:.0%}; falling = seeds whose team return over the last 20% of training "
                      "episodes is below that over the first 20% (seeds with fewer than 50 episodes not counted).")
SEEDS_CAPTION = ("Every seed of every learned configuration: success rate per seed (mean over its evaluation "
                 "episodes, in seed order), their mean, standard deviation over seeds (percentage points) and "
                 f"minimum; collapsed = seeds below {COLLAPSE:.0%}; falling = seeds whose team return over the "
                 "last 20% of training episodes is below that over the first 20%.")
SEEDS_LIFELONG = ("Lifelong rows (task lifelong) show throughput (goals reached per step) per seed, its mean, SD "
                  "and minimum in goals per step, where one-shot rows show success. " + LIFELONG_COLLAPSE)
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


def _cell_scores(evals: pd.DataFrame) -> pd.DataFrame:
    """Per (cell_id, execution): the cell's task, its score (mean over episodes of success, or
    of throughput for a lifelong cell) and the collapse floor of that score: ``COLLAPSE``, or for
    a lifelong cell ``COLLAPSE`` times the best mean throughput over seeds of any method and mode
    at its (N, p) (docs/decisions/0238)."""
    scored = with_score(evals)
    per = scored.groupby(["cell_id", "execution"]).agg(task=("task", "first"), score=("score", "mean"),
                                                       n_robots=("n_robots", "first"), loss_p=("loss_p", "first"))
    life = scored[scored["task"] == "lifelong"]
    best = (life.groupby(["method", "n_robots", "loss_p", "execution"])["score"].mean()
            .groupby(["n_robots", "loss_p"]).max())
    floor = [COLLAPSE * float(best[(n, p)]) if t == "lifelong" else COLLAPSE
             for t, n, p in zip(per["task"], per["n_robots"], per["loss_p"], strict=True)]
    return per.assign(floor=floor)


def collapse_mode(modes: pd.Series) -> str | None:
    """The execution mode a seed's collapse is judged in (module doc): sample where the run
    evaluated it, else the first of the run's order; None for no evaluation row."""
    present = set(map(str, modes))
    return "sample" if "sample" in present else next(iter(execution_order(present)), None)


def robustness_frame(train: pd.DataFrame, evals: pd.DataFrame, variants: pd.Series | None = None) -> pd.DataFrame:
    """One row per learned method, variant and N: seeds, collapsed seeds, seeds with a
    curve, falling ones. ``variants``: cell_id -> variant label (``cell_variants``)."""
    if train.empty:
        return pd.DataFrame(columns=COLUMNS)
    learned = set(map(str, train["method"]))
    mode = collapse_mode(evals["execution"])
    scores = _cell_scores(evals[evals["execution"] == mode] if mode is not None else evals.iloc[0:0])
    scores = scores.reset_index(level="execution", drop=True)
    learned_ids = set(map(str, evals.loc[evals["method"].isin(learned), "cell_id"]))
    scores = scores[scores.index.isin(learned_ids)]
    falling = _falling(train)
    cells = _labels(train[["method", "n_robots", "cell_id"]].drop_duplicates(), variants)
    cells["task"] = cells["cell_id"].astype(str).map(scores["task"]).fillna("one-shot")  # tasks never pooled
    rows = []
    for (task, method, label, n), g in cells.groupby(["task", "method", "label", "n_robots"], sort=True):
        ids = [c for c in map(str, g["cell_id"]) if c in scores.index]
        falls = [falling[c] for c in map(str, g["cell_id"]) if c in falling]
        collapsed = int(sum(scores.at[c, "score"] < scores.at[c, "floor"] for c in ids))
        rows.append({"task": task, "method": str(method), "label": str(label), "n_robots": int(n),
                     "seeds": len(ids), "collapsed": collapsed,
                     "collapsed_share": collapsed / len(ids) if ids else float("nan"),
                     "curves": len(falls), "falling": int(sum(falls)),
                     "falling_share": sum(falls) / len(falls) if falls else float("nan")})
    frame = _ordered(pd.DataFrame(rows, columns=["task", *COLUMNS]), ["task", "n_robots"])
    return frame if (frame["task"] == "lifelong").any() else frame.drop(columns="task")


def seeds_frame(train: pd.DataFrame, evals: pd.DataFrame, variants: pd.Series | None = None) -> pd.DataFrame:
    """One row per learned method, variant, N, p and execution mode: each seed's success
    rate, or throughput for a lifelong cell (seed order), and their summary (module doc); a
    run with lifelong cells gets a ``task`` column."""
    if train.empty or evals.empty:
        return pd.DataFrame(columns=SEED_COLUMNS)
    learned = set(map(str, train["method"]))
    per_cell = _cell_scores(evals)
    ev = evals[evals["method"].isin(learned)]
    falling = _falling(train)
    cells = _labels(ev[["method", "n_robots", "loss_p", "seed", "cell_id"]].drop_duplicates("cell_id"), variants)
    rows = []
    for (method, label, n, p), g in cells.groupby(["method", "label", "n_robots", "loss_p"], sort=True):
        g = g.sort_values("seed")
        falls = [falling[c] for c in map(str, g["cell_id"]) if c in falling]
        mine = per_cell[per_cell.index.get_level_values("cell_id").isin(g["cell_id"])]
        for task in [t for t in ("one-shot", "lifelong") if t in set(mine["task"])]:
            of_task = mine[mine["task"] == task]
            for mode in execution_order(set(of_task.index.get_level_values("execution"))):
                picked = [(c, mode) for c in g["cell_id"] if (c, mode) in of_task.index]
                rates, floors = of_task.loc[picked, "score"].to_numpy(), of_task.loc[picked, "floor"].to_numpy()
                shown = (", ".join(f"{r:.1%}" for r in rates) if task == "one-shot"
                         else ", ".join(f"{r:.3g}" for r in rates))
                rows.append({"task": task, "method": str(method), "label": str(label), "n_robots": int(n),
                             "loss_p": float(p), "execution": mode, "seeds": len(rates), "success_by_seed": shown,
                             "mean": float(rates.mean()), "sd_pp": float(100 * rates.std(ddof=1)) if len(rates) > 1
                             else float("nan"), "min": float(rates.min()), "collapsed": int((rates < floors).sum()),
                             "curves": len(falls), "falling": int(sum(falls))})
    frame = _ordered(pd.DataFrame(rows, columns=["task", *SEED_COLUMNS]), ["n_robots", "loss_p"])
    return frame if (frame["task"] == "lifelong").any() else frame.drop(columns="task")


def _share(k: int, n: int) -> str:
    return "—" if n == 0 else f"{k}/{n} ({k / n:.0%})"


def robustness_display(frame: pd.DataFrame) -> pd.DataFrame:
    """The table as the index shows it: method, N, collapsed k/n (share), falling k/n (share)."""
    return pd.DataFrame({"method": frame["label"], **({"task": frame["task"]} if "task" in frame else {}),
                         "N": frame["n_robots"].astype(str),
                         "collapsed seeds": [_share(r.collapsed, r.seeds) for r in frame.itertuples()],
                         "falling returns": [_share(r.falling, r.curves) for r in frame.itertuples()]})


def _table(shown: pd.DataFrame) -> list[str]:
    return ["| " + " | ".join(shown.columns) + " |", "|" + "---|" * len(shown.columns),
            *("| " + " | ".join(map(str, r)) + " |" for r in shown.itertuples(index=False))]


def robustness_markdown(frame: pd.DataFrame) -> str:
    """``robustness.md``: the caption and the table."""
    lines = ["# Robustness of training", "", ROBUSTNESS_CAPTION + (" " + LIFELONG_COLLAPSE if "task" in frame else ""),
             ""]
    if frame.empty:
        return "\n".join(lines + ["The run has no training rows (no learned method, or none done)."]) + "\n"
    return "\n".join(lines + _table(robustness_display(frame))) + "\n"


def seeds_markdown(frame: pd.DataFrame) -> str:
    """``seeds.md``: the caption and one row per configuration and mode; a lifelong row shows
    throughput (goals per step, its SD in goals per step) where a one-shot row shows success."""
    lifelong = "task" in frame and bool((frame["task"] == "lifelong").any())
    lines = ["# Every seed", "", SEEDS_CAPTION + (" " + SEEDS_LIFELONG if lifelong else ""), ""]
    if frame.empty:
        return "\n".join(lines + ["The run has no evaluated learned cell."]) + "\n"
    life = frame["task"].eq("lifelong").to_numpy() if lifelong else np.zeros(len(frame), dtype=bool)
    def value(v: float, rate: bool) -> str:
        return f"{v:.1%}" if rate else f"{v:.3g}"
    shown = pd.DataFrame({
        "method": frame["label"], "N": frame["n_robots"].astype(str), "p": frame["loss_p"].map(fmt_p),
        "mode": frame["execution"],
        **({"task": frame["task"]} if lifelong else {}),
        ("success (throughput) per seed" if lifelong else "success per seed"): frame["success_by_seed"],
        "mean": [value(v, not x) for v, x in zip(frame["mean"], life, strict=True)],
        "SD (pp)": [("—" if v != v else f"{v:.1f}" if not x else f"{v / 100:.3g}")
                    for v, x in zip(frame["sd_pp"], life, strict=True)],
        "min": [value(v, not x) for v, x in zip(frame["min"], life, strict=True)],
        "collapsed": [f"{r.collapsed}/{r.seeds}" for r in frame.itertuples()],
        "falling": [f"{r.falling}/{r.curves}" if r.curves else "—" for r in frame.itertuples()]})
    if lifelong:
        shown = shown.rename(columns={"SD (pp)": "SD (pp; goals/step)"})
    return "\n".join(lines + _table(shown)) + "\n"
