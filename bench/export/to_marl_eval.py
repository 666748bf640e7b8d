"""``bench export --format marl-eval``: a run's evaluations in marl-eval's raw-data JSON.

marl-eval (instadeepai/marl-eval, PyPI ``id-marl-eval``) reads one nested dict::

    {environment: {task: {algorithm: {run: {"step_0": {"step_count": int, metric: [..]},
                                             "absolute_metrics": {metric: [..]}}}}}}

Here environment = ``warehouse_v0``; task = ``<layout>_n<N>_p<p>`` (plus the loss model
when not Bernoulli); algorithm = the method name (with a short hash of the other settings
when one task holds several variants of a method, e.g. the ablation grid); run =
``seed_<seed>``. The bench evaluates a policy once, after training, so each run has one
logged step, ``step_0``: ``step_count`` = the environment steps the cell trained (0 for
PIBT), one value per evaluation episode for each metric; ``absolute_metrics`` holds the same
lists (marl-eval's absolute metric is a larger evaluation of the best policy; ours is the
final policy's whole evaluation). Metrics: every eval column that is finite in every
exported episode (NaN columns such as ``mean_candidates`` without a filter are left out,
since marl-eval needs the same metrics everywhere), ``team_return`` under marl-eval's name
``return``. One execution mode (default argmax;
PIBT always ``planner``, its only mode). ``balanced`` keeps what marl-eval's matrices
need: the tasks every exported algorithm ran, and the same seeds (the lowest ones,
as many as the sparsest pair has) everywhere (docs/decisions/0167).
"""
from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Any

import pandas as pd

from bench.store.schema import METRIC_FIELDS
from envs.errors import BenchError

ENVIRONMENT = "warehouse_v0"
METRICS = [f.name for f in METRIC_FIELDS]
# marl-eval's own name for the return (the metric its examples normalize); marl-eval picks
# plotted metrics by splitting names at "_", so "team_return" would not be recognized.
NAMES = {"team_return": "return"}


def _task(row: pd.Series) -> str:
    task = f"{Path(str(row['layout'])).stem}_n{int(row['n_robots'])}_p{float(row['loss_p']):g}"
    if str(row.get("loss_model", "bernoulli")) != "bernoulli":
        task += f"_{row['loss_model']}"
    return task


def _variant(row: pd.Series) -> str:
    """Hash of the cell's config without its method, seed, N, p and layout."""
    config = json.loads(str(row["config_json"]))
    for k in ("seed", "n_robots", "loss_p", "layout", "loss_model"):
        config.pop(k, None)
    return hashlib.sha256(json.dumps(config, sort_keys=True).encode()).hexdigest()[:6]


def marl_eval_data(cells: pd.DataFrame, train: pd.DataFrame, evals: pd.DataFrame,
                   execution: str = "argmax", balanced: bool = False) -> dict[str, Any]:
    """The marl-eval dict of a run's done cells (see the module docstring)."""
    done = cells[cells["status"] == "done"].copy()
    if done.empty:
        raise BenchError("bench export: the run has no done cell to export")
    done["task"] = done.apply(_task, axis=1)
    done["variant"] = done.apply(_variant, axis=1)
    n_variants = done.groupby(["task", "method"])["variant"].transform("nunique")
    done["algorithm"] = [m if k == 1 else f"{m}-{v}" for m, v, k in
                         zip(done["method"], done["variant"], n_variants, strict=True)]
    modes = {cid: ("planner" if "planner" in str(ex).split(",") else execution)
             for cid, ex in zip(done["cell_id"], done["executions"], strict=True)}
    known = {m for ex in done["executions"] for m in str(ex).split(",")}
    if execution not in known:
        raise BenchError(f"--execution {execution!r}: no cell of the run was evaluated in that mode "
                         f"(modes: {', '.join(sorted(known))})")
    ev = evals[evals["cell_id"].map(modes).eq(evals["execution"])]
    if balanced:
        done = _balanced(done)
    ev = ev[ev["cell_id"].isin(set(done["cell_id"]))]
    metrics = [m for m in METRICS if m in ev and ev[m].notna().all()]
    steps = train.groupby("cell_id")["steps"].sum() if len(train) else pd.Series(dtype=float)
    by_cell = {cid: g.sort_values("episode") for cid, g in ev.groupby("cell_id")}
    data: dict[str, Any] = {ENVIRONMENT: {}}
    for row in done.sort_values(["n_robots", "loss_p", "task", "algorithm", "seed"]).itertuples():
        g = by_cell.get(row.cell_id)
        if g is None or g.empty:
            continue
        values = {NAMES.get(m, m): [float(v) for v in g[m]] for m in metrics}
        run = {"step_0": {"step_count": int(steps.get(row.cell_id, 0)), **values},
               "absolute_metrics": {m: list(v) for m, v in values.items()}}
        runs = data[ENVIRONMENT].setdefault(row.task, {}).setdefault(row.algorithm, {})
        runs[f"seed_{int(row.seed)}"] = run
    _check_finite(data)
    return data


def _balanced(done: pd.DataFrame) -> pd.DataFrame:
    """The tasks that every algorithm ran, with the same (lowest) seeds in every pair."""
    algorithms = set(done["algorithm"])
    tasks = [t for t, g in done.groupby("task") if set(g["algorithm"]) == algorithms]
    kept = done[done["task"].isin(tasks)]
    if kept.empty:
        raise BenchError("bench export --balanced: no task was run by every method of the run; "
                         "export without --balanced or with fewer methods (--methods)")
    k = int(kept.groupby(["task", "algorithm"]).size().min())
    kept = kept.sort_values("seed")
    return kept.groupby(["task", "algorithm"], group_keys=False).head(k)


def _check_finite(data: dict[str, Any]) -> None:
    for tasks in data.values():
        for algs in tasks.values():
            for runs in algs.values():
                for run in runs.values():
                    for step in run.values():
                        for k, v in step.items():
                            vals = v if isinstance(v, list) else [v]
                            assert all(math.isfinite(x) for x in vals), k
