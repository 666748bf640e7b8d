"""The ordering of two learned methods across configurations: an exact sign test.

Per task, learned execution mode and pair of learned methods, over the configurations (N, p)
both ran: at how many each has the higher mean score over seeds (the task's own,
``reports.tables.leaderboard.task_scores``: success of one-shot cells, throughput of lifelong
cells; a lifelong configuration is never counted with a one-shot one, docs/decisions/0235), and the exact sign test
(``scipy.stats.binomtest``, p = 1/2, ties left out) of "X above Y more often than not",
one-sided each way at ``SIGN_ALPHA`` = 0.05 / 4 (the fixed level of docs/decisions/0230). This
is the pooled test that carries a statement like "method X beats Y across the grid": each
configuration's own comparison may be within noise, their directions together are not.
Configurations are independent cells (their seeds are separate trainings).
"""
from __future__ import annotations

from itertools import combinations

import numpy as np
import pandas as pd
from scipy import stats as sps

from reports.data.store import execution_order
from reports.figures.plotting import label_order, method_label
from reports.stats import ALPHA
from reports.tables.leaderboard import PLANNER, task_scores
from reports.tables.mapf import SCORE_NAME, TASKS

__all__ = ["ORDERING_COLUMNS", "ORDERING_HEADING", "SIGN_ALPHA", "ordering_frame", "ordering_markdown"]

SIGN_ALPHA = ALPHA / 4
ORDERING_HEADING = "## Ordering across configurations (sign test)"
ORDERING_COLUMNS = ["task", "execution", "method", "over", "configurations", "above", "below", "ties",
                    "p_above", "p_below", "verdict"]


def ordering_frame(evals: pd.DataFrame) -> pd.DataFrame:
    """One row per (task, learned mode, pair of learned methods), the pair ordered so that
    ``method`` is above ``over`` at least as often as below; ``verdict`` "above",
    "below" or "undecided" at ``SIGN_ALPHA``. Each task is compared on its own score."""
    scores = task_scores(evals)
    means = scores.groupby(["task", "execution", "method", "n_robots", "loss_p"])["score"].mean()
    rows = []
    for task in [t for t in TASKS if t in set(scores["task"])]:
        of_task = means.loc[task]
        for mode in [m for m in execution_order(scores["execution"]) if m != PLANNER]:
            if mode not in of_task.index.get_level_values(0):
                continue
            rows += [{"task": task, "execution": mode, **r} for r in _pairs(of_task.loc[mode].unstack(["n_robots",
                                                                                                      "loss_p"]))]
    return pd.DataFrame(rows, columns=ORDERING_COLUMNS)


def _pairs(part: pd.DataFrame) -> list[dict]:
    """The sign test of every pair of ``part``'s methods (rows) over its configurations (columns)."""
    rows = []
    methods = sorted(part.index, key=lambda m: (label_order(method_label(m)), m))
    for x, y in combinations(methods, 2):
        both = part.loc[[x, y]].dropna(axis=1)
        if both.shape[1] == 0:
            continue
        d = both.loc[x].to_numpy() - both.loc[y].to_numpy()
        above, below = int((d > 0).sum()), int((d < 0).sum())
        if below > above:
            x, y, above, below = y, x, below, above
        n = above + below
        p_above = float(sps.binomtest(above, n, 0.5, alternative="greater").pvalue) if n else np.nan
        p_below = float(sps.binomtest(above, n, 0.5, alternative="less").pvalue) if n else np.nan
        verdict = "above" if p_above < SIGN_ALPHA else "below" if p_below < SIGN_ALPHA else "undecided"
        rows.append({"method": x, "over": y, "configurations": int(both.shape[1]),
                     "above": above, "below": below, "ties": int(both.shape[1]) - n,
                     "p_above": p_above, "p_below": p_below, "verdict": verdict})
    return rows


def ordering_markdown(frame: pd.DataFrame) -> str:
    """The section of leaders.md: one line per pair and mode, a column for the task (and its
    score) where the run holds lifelong cells."""
    tasks = list(dict.fromkeys(frame["task"])) if len(frame) else []
    score = " / ".join(f"{SCORE_NAME[t]} ({t} cells)" for t in tasks) if tasks != ["one-shot"] and tasks \
        else "success"
    lines = [ORDERING_HEADING, "",
             "Per learned execution mode and pair of learned methods: at how many of the configurations both "
             f"ran each has the higher mean {score} over seeds, and the exact sign test (scipy's `binomtest`, "
             f"ties left out) of the first above the second, one-sided at {SIGN_ALPHA:g} "
             "(docs/decisions/0230). \"above\": the first is above the second across the grid; "
             "\"undecided\": the directions could be a fair coin's."
             + (" Each task is compared on its own score, over its own configurations; no lifelong "
                "configuration is counted with a one-shot one (docs/decisions/0235)." if "lifelong" in tasks else ""),
             ""]
    if frame.empty:
        return "\n".join(lines + ["No two learned methods share a configuration.", ""])
    lifelong = "lifelong" in tasks
    lines += ["| " + ("task (score) | " if lifelong else "") + "mode | method | over | above / below (ties) of "
              "configurations | sign test p | verdict |", "|---" * (7 if lifelong else 6) + "|"]
    for r in frame.itertuples(index=False):
        lines.append("| " + (f"{r.task} ({SCORE_NAME[r.task]}) | " if lifelong else "")
                     + f"{r.execution} | {method_label(r.method)} | {method_label(r.over)} | "
                     f"{r.above} / {r.below} ({r.ties}) of {r.configurations} | {r.p_above:.2g} | {r.verdict} |")
    return "\n".join(lines) + "\n"
