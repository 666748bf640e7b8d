"""The ordering of two learned methods across configurations: an exact sign test.

Per learned execution mode and pair of learned methods, over the configurations (N, p) both
ran: at how many each has the higher mean success over seeds, and the exact sign test
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
from reports.tables.leaderboard import PLANNER, seed_scores

__all__ = ["ORDERING_COLUMNS", "ORDERING_HEADING", "SIGN_ALPHA", "ordering_frame", "ordering_markdown"]

SIGN_ALPHA = ALPHA / 4
ORDERING_HEADING = "## Ordering across configurations (sign test)"
ORDERING_COLUMNS = ["execution", "method", "over", "configurations", "above", "below", "ties",
                    "p_above", "p_below", "verdict"]


def ordering_frame(evals: pd.DataFrame) -> pd.DataFrame:
    """One row per (learned mode, pair of learned methods), the pair ordered so that
    ``method`` is above ``over`` at least as often as below; ``verdict`` "above",
    "below" or "undecided" at ``SIGN_ALPHA``."""
    scores = seed_scores(evals)
    means = scores.groupby(["execution", "method", "n_robots", "loss_p"])["success_rate"].mean()
    rows = []
    for mode in [m for m in execution_order(scores["execution"]) if m != PLANNER]:
        part = means.loc[mode].unstack(["n_robots", "loss_p"]) if mode in means.index.get_level_values(0) else None
        if part is None:
            continue
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
            rows.append({"execution": mode, "method": x, "over": y, "configurations": int(both.shape[1]),
                         "above": above, "below": below, "ties": int(both.shape[1]) - n,
                         "p_above": p_above, "p_below": p_below, "verdict": verdict})
    return pd.DataFrame(rows, columns=ORDERING_COLUMNS)


def ordering_markdown(frame: pd.DataFrame) -> str:
    """The section of leaders.md: one line per pair and mode."""
    lines = [ORDERING_HEADING, "",
             "Per learned execution mode and pair of learned methods: at how many of the configurations both "
             "ran each has the higher mean success over seeds, and the exact sign test (scipy's `binomtest`, "
             f"ties left out) of the first above the second, one-sided at {SIGN_ALPHA:g} "
             "(docs/decisions/0230). \"above\": the first is above the second across the grid; "
             "\"undecided\": the directions could be a fair coin's.", ""]
    if frame.empty:
        return "\n".join(lines + ["No two learned methods share a configuration.", ""])
    lines += ["| mode | method | over | above / below (ties) of configurations | sign test p | verdict |",
              "|---|---|---|---|---|---|"]
    for r in frame.itertuples(index=False):
        lines.append(f"| {r.execution} | {method_label(r.method)} | {method_label(r.over)} | "
                     f"{r.above} / {r.below} ({r.ties}) of {r.configurations} | {r.p_above:.2g} | {r.verdict} |")
    return "\n".join(lines) + "\n"
