"""The MAPF metrics of a run: CSR, sum of costs and makespan of one-shot cells,
throughput of lifelong cells, per configuration.

Eval rows carry ``csr``, ``sum_of_costs``, ``makespan`` (one-shot episodes) and
``throughput`` (lifelong episodes: goals per step); each is NaN where it does not apply and
in every row of a store written before these columns (bench/store/schema.py
``ADDED_EVAL_COLUMNS``). One row per (method, N, p, variant, execution mode) whose rows hold
a finite value of any of them; every metric is the mean over seeds of per-seed means with a
95% CI over seeds inside the metric's range (a bootstrap over episodes with a single seed), by the summary's
``metric_estimate`` (reports.stats). Variants (e.g. ``delay=2``) are never pooled.

A store without any finite MAPF value gives an empty frame, and the report then writes
nothing for it: older reports rebuild byte for byte.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from reports.data.store import execution_order, fmt_p
from reports.data.variants import cell_variants, variant_suffix
from reports.tables.summary import KEYS, fmt_ci, metric_estimate

ONE_SHOT = ("csr", "sum_of_costs", "makespan")
LIFELONG = ("throughput",)
MAPF_METRICS = ONE_SHOT + LIFELONG
KIND = {"csr": "pct", "sum_of_costs": "num", "makespan": "num", "throughput": "num"}
HEAD = {"csr": "CSR", "sum_of_costs": "sum of costs", "makespan": "makespan",
        "throughput": "throughput (goals/step)"}
CAPTION = ("MAPF metrics: one-shot cells: CSR (episodes where every robot reached its goal), sum of "
           "costs and makespan (steps); lifelong cells: throughput (goals reached per step). Mean over "
           "seeds [95% CI]: over seeds with two or more seeds (a Student t interval on the logit scale for "
           "CSR, Cox's lognormal interval for costs and throughput: inside their range), else a bootstrap "
           "over the single seed's evaluation episodes (column \"CI over\"); — where a metric does not "
           "apply to the cell's task.")


def has_mapf(evals: pd.DataFrame) -> bool:
    """Whether any eval row holds a finite MAPF metric (a store written since they exist)."""
    cols = [c for c in MAPF_METRICS if c in evals]
    return bool(cols) and bool(np.isfinite(evals[cols].to_numpy(dtype=np.float64)).any())


TASKS = ("one-shot", "lifelong")  # report order
SCORE = {"one-shot": "success_rate", "lifelong": "throughput"}  # each task's score (docs/decisions/0235)
SCORE_NAME = {"one-shot": "success", "lifelong": "throughput"}


def row_tasks(evals: pd.DataFrame) -> pd.Series:
    """Per eval row, its cell's task: "lifelong" where the row holds a finite throughput (only
    lifelong episodes have one), else "one-shot" (also every row of a store written before
    the MAPF columns)."""
    if "throughput" not in evals:
        return pd.Series("one-shot", index=evals.index, dtype=object)
    finite = np.isfinite(evals["throughput"].to_numpy(dtype=np.float64))
    return pd.Series(np.where(finite, "lifelong", "one-shot"), index=evals.index, dtype=object)


def has_lifelong(evals: pd.DataFrame) -> bool:
    """Whether any eval row is of a lifelong cell: the score frames then carry a ``task`` column."""
    return bool(len(evals)) and bool(row_tasks(evals).eq("lifelong").any())


def tasks_of(evals: pd.DataFrame) -> list[str]:
    """The tasks of ``evals``' rows in report order (one-shot first)."""
    present = set(row_tasks(evals))
    return [t for t in TASKS if t in present]


def with_score(evals: pd.DataFrame) -> pd.DataFrame:
    """``evals`` with ``task`` and ``score``: each row's task and its task's score (success
    of a one-shot row, throughput of a lifelong row); never one against the other."""
    tasks = row_tasks(evals)
    success = evals["success_rate"].to_numpy(dtype=np.float64)
    score = (np.where(tasks.eq("lifelong"), evals["throughput"].to_numpy(dtype=np.float64), success)
             if "throughput" in evals else success)
    return evals.assign(task=tasks, score=score)


def is_lifelong(evals: pd.DataFrame) -> bool:
    """A lifelong run: every eval row has a finite throughput (one-shot rows hold NaN)."""
    return bool(len(evals)) and "throughput" in evals and bool(np.isfinite(
        evals["throughput"].to_numpy(dtype=np.float64)).all())


def mapf_frame(evals: pd.DataFrame, cells: pd.DataFrame) -> pd.DataFrame:
    """One row per (method, N, p, variant, execution mode) with a finite MAPF metric: seeds,
    task (one-shot or lifelong) and each metric's mean, ``_lo`` and ``_hi``."""
    columns = [*KEYS, "variant", "execution", "task", "seeds", "ci_over",
               *[f"{m}{s}" for m in MAPF_METRICS for s in ("", "_lo", "_hi")]]
    if evals.empty or not has_mapf(evals):
        return pd.DataFrame(columns=columns)
    cells = cells.assign(variant=cells["cell_id"].map(cell_variants(cells)).fillna(""))
    out = []
    for (method, n, p, variant), group_cells in cells.groupby([*KEYS, "variant"], sort=True):
        group = evals[evals["cell_id"].isin(group_cells["cell_id"])]
        for mode in execution_order(group["execution"]):
            rows = group[group["execution"] == mode]
            if not has_mapf(rows):
                continue
            rec: dict[str, object] = {"method": method, "n_robots": int(n), "loss_p": float(p),
                                      "variant": variant, "execution": mode,
                                      "task": "lifelong" if is_lifelong(rows) else "one-shot",
                                      "seeds": rows["cell_id"].nunique(), "ci_over": "-"}
            for m in MAPF_METRICS:
                mean, lo, hi, unit = metric_estimate(rows, m)
                rec[m], rec[f"{m}_lo"], rec[f"{m}_hi"] = mean, lo, hi
                rec["ci_over"] = unit if unit != "-" else rec["ci_over"]
            out.append(rec)
    return pd.DataFrame(out, columns=columns)


def mapf_display(frame: pd.DataFrame) -> pd.DataFrame:
    """The MAPF table as display strings, one row per configuration, variant and mode."""
    head = ["method", "N", "p", "execution", "task", "seeds", *[HEAD[m] for m in MAPF_METRICS], "CI over"]
    rows = [[str(r["method"]) + variant_suffix(str(r["variant"] or "")), str(r["n_robots"]), fmt_p(r["loss_p"]),
             str(r["execution"]), str(r["task"]), str(r["seeds"]),
             *[fmt_ci(r[m], r[f"{m}_lo"], r[f"{m}_hi"], KIND[m]) for m in MAPF_METRICS], str(r["ci_over"])]
            for _, r in frame.iterrows()]
    return pd.DataFrame(rows, columns=head)


def mapf_markdown(frame: pd.DataFrame) -> str:
    """mapf.md: the caption and the table."""
    shown = mapf_display(frame)
    lines = ["# MAPF metrics of every configuration", "", CAPTION, "",
             "| " + " | ".join(shown.columns) + " |", "|" + "---|" * len(shown.columns)]
    lines += ["| " + " | ".join(r) + " |" for r in shown.itertuples(index=False)]
    return "\n".join(lines) + "\n"
