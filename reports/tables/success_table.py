"""Success rate of every configuration, one row per (N, p, method), one column per execution mode.

``success_by_mode.md`` in the report and, for the committed reproduction, the README's
results table (copied by ``scripts/sync_readme_claims.py``, kept equal by
``tests/reproduction``), so no success rate in the README is typed by hand. Every number
is the summary's (``summary_frame``): the mean over seeds of each seed's mean success over
its evaluation episodes, with the 95% interval over seeds (a Student t interval on the logit
scale, inside [0, 1] by construction; a bootstrap over
episodes for a single seed, marked). Configurations with no evaluation rows yet are listed
as pending, so the table also says what is missing.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from reports.data.store import execution_order
from reports.data.variants import cell_tasks, cell_variants, variant_suffix
from reports.figures.plotting import label_order, method_label
from reports.tables.mapf import TASKS
from reports.tables.summary import FILTER_NOTE, filter_text, fmt_ci

CAPTION = (
    "Success rate (% of robots at their goal at the end of an evaluation episode): mean over seeds "
    "of each seed's mean over its evaluation episodes [95% interval over seeds: a Student t interval on "
    "the logit scale, inside 0-100% by construction]; every mode on the same evaluation scenarios and "
    "loss draws. * : one seed, bootstrap "
    "interval over its episodes. pending: no evaluation rows yet; empty: not a mode of that method.")
LIFELONG_CAPTION = (
    "Throughput (goals reached per step: the score of lifelong cells, where a robot gets its next goal on "
    "arrival, so success, robots at their goal at the horizon, says little; it is in summary.md): mean over "
    "seeds of each seed's mean over its evaluation episodes [95% interval over seeds: Cox's lognormal "
    "interval, at or above 0 by construction]; every mode on the same evaluation scenarios and loss draws. "
    "* : one seed, bootstrap interval over its episodes. pending: no evaluation rows yet; empty: not a mode "
    "of that method.")
HEADING = {"one-shot": "## One-shot cells: success rate", "lifelong": "## Lifelong cells: throughput"}


def success_frame(summary: pd.DataFrame, cells: pd.DataFrame, task: str = "one-shot") -> pd.DataFrame:
    """Display strings: N, p, method (with its variant, ``reports.data.variants``), seeds
    (done/cells), then one column per execution mode of the run's cells (``executions`` of
    cells.parquet); a configuration's own modes read "pending" until it has evaluation rows,
    the modes it does not have stay empty. Only the configurations of cells of ``task``
    (``reports.data.variants.cell_tasks``): a one-shot cell shows its success, a lifelong cell
    its throughput (docs/decisions/0235)."""
    if summary.empty:
        return pd.DataFrame(columns=["N", "p", "method", "seeds"])
    variants = cells["cell_id"].map(cell_variants(cells)).fillna("")  # labelled among all cells, as the summary
    mine = cells["cell_id"].map(cell_tasks(cells)).eq(task).to_numpy()
    cells, variants = cells[mine], variants[mine]
    own = {k: execution_order(m for e in g["executions"] for m in str(e).split(",") if m)
           for k, g in cells.assign(variant=variants).groupby(["n_robots", "loss_p", "method", "variant"])}
    modes = execution_order(m for ms in own.values() for m in ms)
    summary = summary if "variant" in summary else summary.assign(variant="")
    score, kind = ("throughput", "num") if task == "lifelong" else ("success_rate", "pct")
    rows = []
    order = sorted((k for k in summary.groupby(["n_robots", "loss_p", "method", "variant"], sort=False).groups
                    if k in own),
                   key=lambda k: (k[0], k[1], label_order(method_label(k[2])), k[2], k[3]))
    for n, p, method, variant in order:
        g = summary[(summary["n_robots"] == n) & (summary["loss_p"] == p) & (summary["method"] == method)
                    & (summary["variant"] == variant)]
        rec = {"N": str(n), "p": f"{p:g}", "method": method_label(method) + variant_suffix(variant),
               "seeds": f"{int(g['seeds'].max())}/{int(g['cells'].iloc[0])}"}
        by_mode = {r["execution"]: r for _, r in g.iterrows()}
        for mode in modes:
            r = by_mode.get(mode)
            if r is not None and np.isfinite(r[score]):
                star = "*" if r["ci_over"] == "episodes" else ""
                rec[mode] = fmt_ci(r[score], r[f"{score}_lo"], r[f"{score}_hi"], kind) + star + (
                    filter_text(r["correction_rate"], r["fallback_rate"]) if _filtered(r) else "")
            else:
                rec[mode] = "pending" if mode in own.get((n, p, method, variant), []) else ""
        rows.append(rec)
    return pd.DataFrame(rows)  # columns in the records' order: N, p, method, seeds, modes


def _filtered(r: pd.Series) -> bool:
    """Whether a summary row's method ran a safety filter (its rates go beside its score)."""
    return bool(r.get("safety_filter", False)) and "fallback_rate" in r


def success_markdown(summary: pd.DataFrame, cells: pd.DataFrame) -> str:
    """The table as Markdown with its caption under it (what the README shows); a run with
    lifelong cells: their throughput in a table of their own, never beside a success."""
    tasks = [t for t in TASKS if t in set(cell_tasks(cells))] or ["one-shot"]
    parts = []
    for task in tasks:
        frame = success_frame(summary, cells, task)
        head = list(frame.columns)
        lines = ([HEADING[task], ""] if len(tasks) > 1 else []) + [
            "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(str(v) for v in row) + " |" for row in frame.itertuples(index=False)]
        if frame.empty:
            lines.append("\n(no cells in the store)")
        caption = LIFELONG_CAPTION if task == "lifelong" else CAPTION
        if frame.map(lambda v: "(fallback " in str(v)).to_numpy().any():
            caption += " " + FILTER_NOTE
        parts.append("\n".join(lines) + "\n\n" + caption + "\n")
    return "\n".join(parts)
