"""Summary of every configuration group (method x N x p x execution mode) with CIs.

One row per configuration and execution mode (argmax, sample, sample@T; planner for PIBT;
every mode ran on the same evaluation scenarios, docs/decisions/0068). For each row: number of cells (all statuses)
and of done seeds, evaluation episodes,
and for success rate, team return, collision rate, correction rate and payload the mean
over seeds of per-seed evaluation means with a 95% CI over seeds inside the metric's range (a bootstrap CI
over evaluation episodes when a group has a single seed: the column ``ci_over`` says which).
Success rate and team return also get the interquartile mean over pooled evaluation
episodes (robust to a few degenerate episodes, as rliable recommends).
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from reports.data.store import execution_order, fmt_pct
from reports.data.variants import cell_variants, variant_suffix
from reports.stats import bootstrap_ci, iqm, mean_ci, positive_ci, rate_ci

SUMMARY_METRICS = ("success_rate", "team_return", "collision_rate", "correction_rate", "fallback_rate",
                   "payload_scalars_per_step")
LIFELONG_METRICS = ("throughput",)  # a store with lifelong rows: their score too (docs/decisions/0235)
IQM_METRICS = ("success_rate", "team_return")
KEYS = ["method", "n_robots", "loss_p"]


def metric_estimate(rows: pd.DataFrame, metric: str, seed: int = 0) -> tuple[float, float, float, str]:
    """(mean, lo, hi, unit) of ``metric`` over evaluation rows of one configuration.

    Mean over seeds (cells) of per-seed means with a Student t CI over seeds (a seed
    bootstrap covers 50-75% at 2-3 seeds), on the logit scale for a rate and the log scale
    for a count (``metric_range``), so inside the range by construction; with a single seed, the mean and a
    bootstrap CI over its evaluation episodes (unit "episodes"). NaNs are ignored.
    """
    per_seed = rows.groupby("cell_id")[metric].mean().dropna()
    floor, ceil = metric_range(metric)
    if len(per_seed) >= 2:
        x = per_seed.to_numpy()
        ci = rate_ci if (floor, ceil) == (0.0, 1.0) else positive_ci if floor == 0.0 else mean_ci
        mean, lo, hi = ci(x)  # a rate's and a count's interval inside its range by construction
        return mean, lo, hi, "seeds"
    vals = rows[metric].to_numpy(dtype=np.float64)
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return float("nan"), float("nan"), float("nan"), "-"
    lo, hi = bootstrap_ci(vals, seed=seed)
    return float(vals.mean()), lo, hi, "episodes"


def metric_range(metric: str) -> tuple[float, float]:
    """The values ``metric`` can take: [0, 1] for a rate, [0, inf) for counts and payloads,
    else unbounded; a CI stays inside them by construction (``reports.stats.rate_ci``, ``positive_ci``)."""
    if metric.endswith("_rate") or metric == "csr":
        return 0.0, 1.0
    if metric.startswith(("payload", "mean_candidates", "predictor_error", "sum_of_costs", "makespan", "throughput")):
        return 0.0, float("inf")
    return float("-inf"), float("inf")


def summary_frame(evals: pd.DataFrame, cells: pd.DataFrame) -> pd.DataFrame:
    """One row per (method, n_robots, loss_p, variant) group present in ``cells`` and
    execution mode of its evaluation rows (modes in report order; "-" when the group has no
    rows). Variants (``reports.data.variants``) are never pooled: each is its own group."""
    cells = cells.assign(variant=cells["cell_id"].map(cell_variants(cells)).fillna(""))
    lifelong = "throughput" in evals and bool(np.isfinite(evals["throughput"].to_numpy(dtype=np.float64)).any())
    metrics = SUMMARY_METRICS + (LIFELONG_METRICS if lifelong else ())
    out = []
    for key, group_cells in cells.groupby(KEYS + ["variant"], sort=True):
        method, n, p, variant = key
        group = evals[evals["cell_id"].isin(group_cells["cell_id"])]
        for mode in execution_order(group["execution"]) or ["-"]:
            rows = group[group["execution"] == mode]
            out.append({**_summary_row(method, int(n), float(p), mode, rows, group_cells, metrics),
                        "variant": variant})
    return pd.DataFrame(out)


def _summary_row(method: str, n: int, p: float, mode: str, rows: pd.DataFrame,
                 group_cells: pd.DataFrame, metrics: tuple[str, ...] = SUMMARY_METRICS) -> dict[str, object]:
    """The summary of one configuration in one execution mode."""
    status = group_cells["status"]
    rec: dict[str, object] = {
        "method": method, "n_robots": n, "loss_p": p, "execution": mode,
        "cells": len(group_cells), "cells_done": int((status == "done").sum()),
        "cells_failed": int((status == "failed").sum()), "seeds": rows["cell_id"].nunique(),
        "eval_episodes": len(rows),
        "safety_filter": bool(rows["safety_filter"].any()) if len(rows) and "safety_filter" in rows
        else bool(group_cells["safety_filter"].any()),
    }
    unit = "-"
    for m in metrics:
        mean, lo, hi, u = metric_estimate(rows, m) if len(rows) and m in rows else (np.nan,) * 3 + ("-",)
        rec[m], rec[f"{m}_lo"], rec[f"{m}_hi"] = mean, lo, hi
        unit = u if u != "-" else unit
    for m in IQM_METRICS:
        rec[f"{m}_iqm"] = iqm(rows[m].to_numpy()) if len(rows) else np.nan
    rec["ci_over"] = unit
    return rec


def filter_text(correction_rate: float, fallback_rate: float) -> str:
    """What a method that runs a safety filter (the hierarchical method) shows beside each of its
    scores: `` (fallback 1.9%, corrections 16.6%)``, its fallback rate (group-steps that fell back
    to joint Wait / group-steps that ran the filter) and correction rate (robot controls the filter
    changed / active robot-steps), means over seeds; "" for a method without a filter (both NaN)
    (issue 47 item 3, docs/decisions/0236)."""
    if not (np.isfinite(correction_rate) or np.isfinite(fallback_rate)):
        return ""
    def pct(v: float) -> str:  # one decimal like the rest of the page; "<0.1%" where that would read 0.0%
        return "—" if not np.isfinite(v) else "<0.1%" if 0 < v < 0.0005 else f"{100 * v:.1f}%"
    return f" (fallback {pct(fallback_rate)}, corrections {pct(correction_rate)})"


FILTER_NOTE = ("In parentheses beside each score of a method that runs a safety filter (the hierarchical "
               "method): its fallback rate (group-steps that fell back to joint Wait / group-steps that ran "
               "the filter) and correction rate (robot controls the filter changed / active robot-steps), "
               "means over seeds; methods without a filter have none.")


def fmt_ci(v: float, lo: float, hi: float, kind: str) -> str:
    """``kind``: "pct" (a fraction shown in percent), "payload" (scalars per step, one
    decimal with thousands separators, the same everywhere) or "num" (3 significant digits)."""
    if not np.isfinite(v):
        return "—"
    f = {"pct": lambda x: fmt_pct(x, 1) + "%", "payload": lambda x: f"{x:,.1f}",
         "num": lambda x: f"{x:.3g}"}[kind]
    return f"{f(v)} [{f(lo)}, {f(hi)}]" if np.isfinite(lo) else f(v)


SUMMARY_HEAD = ["method", "N", "p", "execution", "seeds (done/cells)", "eval episodes", "success rate",
                "success IQM", "team return", "return IQM", "collision rate", "correction rate", "fallback rate",
                "payload (scalars/step)", "CI over"]
SUMMARY_CAPTION = (
    "Mean over seeds [95% CI]; the CI is a Student t interval over seeds (on the logit scale for "
    "rates, Cox's lognormal interval for counts and payloads, so inside their range by construction) when a "
    "configuration has "
    "two or more done seeds, else a bootstrap over the evaluation episodes of its single seed "
    "(column \"CI over\"). IQM: interquartile mean over pooled evaluation episodes. n/a: the "
    "method has no safety filter. Execution: how controls were picked (argmax; sample = "
    "softmax(logits); sample@T = softmax(logits / T); planner = PIBT), every mode on the same "
    "evaluation scenarios.")


def summary_display(frame: pd.DataFrame) -> pd.DataFrame:
    """The summary as display strings, one row per configuration and execution mode."""
    rows = []
    for _, r in frame.iterrows():
        filt = bool(r.get("safety_filter", True))
        rows.append([
            str(r["method"]) + variant_suffix(str(r.get("variant", "") or "")), str(r["n_robots"]),
                f"{r['loss_p']:g}", str(r["execution"]),
            f"{r['seeds']} ({r['cells_done']}/{r['cells']}"
            + (f", {r['cells_failed']} failed)" if r["cells_failed"] else ")"),
            str(r["eval_episodes"]),
            fmt_ci(r["success_rate"], r["success_rate_lo"], r["success_rate_hi"], "pct"),
            fmt_ci(r["success_rate_iqm"], np.nan, np.nan, "pct"),
            fmt_ci(r["team_return"], r["team_return_lo"], r["team_return_hi"], "num"),
            fmt_ci(r["team_return_iqm"], np.nan, np.nan, "num"),
            fmt_ci(r["collision_rate"], r["collision_rate_lo"], r["collision_rate_hi"], "pct"),
            fmt_ci(r["correction_rate"], r["correction_rate_lo"], r["correction_rate_hi"], "pct")
            if filt else "n/a",
            fmt_ci(r["fallback_rate"], r["fallback_rate_lo"], r["fallback_rate_hi"], "pct") if filt else "n/a",
            fmt_ci(r["payload_scalars_per_step"], r["payload_scalars_per_step_lo"],
                 r["payload_scalars_per_step_hi"], "payload"),
            str(r["ci_over"])])
    return pd.DataFrame(rows, columns=SUMMARY_HEAD)


def ci_display(frame: pd.DataFrame, labels: dict[str, str], metrics: dict[str, tuple[str, str]]) -> pd.DataFrame:
    """Display strings of a frame of (mean, _lo, _hi) columns, e.g. the ablation's:
    ``labels`` maps plain columns to headers, ``metrics`` maps a metric to (header, kind of
    ``fmt_ci``)."""
    out = {h: frame[c].astype(str).tolist() for c, h in labels.items()}
    for m, (h, kind) in metrics.items():
        out[h] = [fmt_ci(v, lo, hi, kind)
                  for v, lo, hi in zip(frame[m], frame[f"{m}_lo"], frame[f"{m}_hi"], strict=True)]
    return pd.DataFrame(out)


def summary_markdown(frame: pd.DataFrame) -> str:
    head = SUMMARY_HEAD
    lines = ["# Summary of every configuration", "", SUMMARY_CAPTION, "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for cells in summary_display(frame).itertuples(index=False):
        lines.append("| " + " | ".join(cells) + " |")
    if frame.empty:
        lines.append("\n(no cells in the store)")
    return "\n".join(lines) + "\n"
