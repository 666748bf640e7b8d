"""Per-configuration summaries of a study: replicates, mean, 95 % CI, and the best point.

A trial is one seed; a configuration ("point") is judged by the mean of its replicates
(SPEC 6: best = highest mean over replicates). Issue #16 saw one configuration score
0.125 and 0.288 on two seeds, so the single highest trial mostly selects a lucky seed.

``point_table`` groups the trials frame (studies/export.py) by the searched parameters.
A point is *eligible* for best when it has at least ``replicates`` complete trials and
none pruned: a pruned replicate was judged below the median, and averaging only the
replicates that survived would bias the point's mean upwards. The CI is Student's t
interval over the complete replicates (with two replicates it is wide: t_{0.975,1} = 12.7,
which is the honest width of two seeds).
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from envs.errors import BenchError
from reports.stats import rate_ci
from studies.space import plain
from studies.trial_columns import FILTER_RATES, param_columns

CONFIDENCE = 0.95


def t_interval(values: np.ndarray, confidence: float = CONFIDENCE) -> tuple[float, float, float]:
    """(mean, low, high) of the objective (an evaluation success rate) over replicates
    ``values`` ((n,) floats): ``reports.stats.rate_ci``, a Student t interval on the logit
    scale, inside [0, 1] by construction; low = high = NaN for fewer than two values."""
    mean, low, high = rate_ci(values, confidence)
    return mean, low, high


def point_table(trials: pd.DataFrame, replicates: int) -> pd.DataFrame:
    """One row per configuration tried: parameters, counts per state, the mean objective
    (``value``), success rate, team return and the safety filter's rates (``FILTER_RATES``)
    over complete replicates, the objective's 95 % CI (``ci_low``, ``ci_high``) and
    ``eligible``; sorted best first (eligible, then mean value, then mean team return)."""
    names = param_columns(trials)
    cols = [*names, "complete", "pruned", "running", "failed", "value", "ci_low", "ci_high",
            "success_rate", "team_return", *FILTER_RATES, "value_return", "trials", "eligible"]
    if not names or trials.empty:
        return pd.DataFrame(columns=cols)
    trials = trials.copy()
    for col in ("value_return", "team_return", "success_rate", *FILTER_RATES):
        if col not in trials:
            trials[col] = math.nan
    rows = []
    for key, part in trials.dropna(subset=names).groupby(names):  # in parameter order
        key = key if isinstance(key, tuple) else (key,)
        comp = part[part["state"] == "COMPLETE"]
        mean, low, high = t_interval(comp["value"].to_numpy(float))
        n_pruned = int((part["state"] == "PRUNED").sum())
        rows.append({
            **{n: plain(v) for n, v in zip(names, key, strict=True)},
            "complete": len(comp), "pruned": n_pruned,
            "running": int(part["state"].isin(["RUNNING", "WAITING"]).sum()),
            "failed": int((part["state"] == "FAIL").sum()),
            "value": mean, "ci_low": low, "ci_high": high,
            # means over the complete replicates (NaN when none is complete, or no filter ran)
            **{col: float(comp[col].mean()) for col in ("success_rate", "team_return", *FILTER_RATES,
                                                        "value_return")},
            "trials": ",".join(str(int(n)) for n in part["number"]),
            "eligible": len(comp) >= replicates and n_pruned == 0,
        })
    table = pd.DataFrame(rows, columns=cols)
    order = table.assign(_ret=table["value_return"].fillna(table["team_return"]))
    # several keys: pandas sorts with a stable lexsort, NaN last, so ties keep parameter order
    order = order.sort_values(["eligible", "value", "_ret"], ascending=[False, False, False])
    return table.loc[order.index].reset_index(drop=True)


def best_point(trials: pd.DataFrame, replicates: int = 2, n_points: int | None = None) -> pd.Series:
    """The eligible configuration with the highest mean objective (ties: mean return).

    ``n_points`` (exhaustive search): no best until every one of the ``n_points``
    configurations has ``replicates`` finished (complete or pruned) replicates. BenchError
    when there is no best yet, naming how far the study is and how to get there.
    """
    if n_points is not None:
        names = param_columns(trials)
        done = trials[trials["state"].isin(["COMPLETE", "PRUNED"])].dropna(subset=names) if names else trials.iloc[:0]
        covered = int((done.groupby(names).size() >= replicates).sum()) if names and len(done) else 0
        if covered < n_points:
            raise BenchError(
                f"no best configuration yet: {covered} of {n_points} configurations have {replicates} "
                f"finished replicates, and an exhaustive search reports a best only once all have; "
                f"rerun bench tune --study NAME (default --trials {n_points * replicates})")
    table = point_table(trials, replicates)
    if table.empty or not bool(table["eligible"].iloc[0]):
        n_points = len(table)
        n_complete = int((table["complete"] >= replicates).sum()) if n_points else 0
        raise BenchError(
            f"no best configuration yet: none of the {n_points} configuration(s) tried has "
            f"{replicates} complete, unpruned replicates ({n_complete} have {replicates} complete); "
            "run more trials (bench tune --study NAME --trials K) or --pruner none")
    return table.iloc[0]


def coverage(trials: pd.DataFrame, n_points: int, replicates: int) -> str:
    """'12 of 20 configurations have >= 2 finished replicates' (complete or pruned)."""
    names = param_columns(trials)
    if not names:
        return f"0 of {n_points} configurations have >= {replicates} finished replicates"
    done = trials[trials["state"].isin(["COMPLETE", "PRUNED"])].dropna(subset=names)
    counts = done.groupby(names).size()
    return f"{int((counts >= replicates).sum())} of {n_points} configurations have >= {replicates} finished replicates"
