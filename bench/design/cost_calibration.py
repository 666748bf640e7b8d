"""What a run's finished cells actually cost, in the units of ``bench/design/costs.py``.

For every done cell of a run directory: its training seconds (the sum of its training
rows' ``wall_s``, each an iteration's seconds divided by its episodes) and its evaluation
seconds (the cell's ``wall_s`` minus those). Dividing the agent-steps ``costs`` charges the
cell (``cell_agent_steps``: episodes x horizon x N, an upper bound) by these seconds gives
*effective* rates, so that ``costs.cell_seconds`` of a cell at an observed rate is the
seconds such a cell took. A cell trained in a seed stack (``bench run --stack-seeds``)
took its share of the stack's time; its training rate is scaled back to one seed by the
stack's gain (``costs.stack_gain``), so that estimates apply the gain once. The stacks are
the ones the manifest's run records list (``stacks``, written since ``--stack-seeds auto``,
docs/decisions/0237), else the ones ``bench run --stack-seeds K`` forms over the run's cells.
``observed_rates`` takes the median per (method, N), over the cells the run trained itself
where it has any (cells copied in from another run may have run stacked or not);
``bench grids --rates-from RUN`` estimates with them, and the built-in rates of ``costs``
(``bench/design/cost_rates.json``, ``rates_file``) are the committed reproduction's.

Wall time: a cell's rate includes whatever else the machine was doing (the other worker,
other processes), as a user's run will.
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pandas as pd

from bench.design import costs
from bench.design.cells import Cell
from bench.design.costs import Rates
from bench.store.run_store import RunStore
from envs.errors import BenchError


def observed_costs(run_dir: Path | str, stack_seeds: int = 1, copied: Iterable[str] = ()) -> pd.DataFrame:
    """One row per done cell of the run: ``method``, ``n_robots``, ``train_s``, ``eval_s``,
    the one-seed ``train_rate`` and the ``eval_rate`` (agent-steps per second; NaN where
    the cell had no such phase, e.g. a planner's training), ``stack`` (the seed stack the
    run trained it in with ``bench run --stack-seeds stack_seeds``) and ``trained_here``
    (False for the ``copied`` cell ids, which another run trained, taken as unstacked)."""
    store = RunStore(run_dir)
    cells = store.read_cells()
    if cells is None:
        raise BenchError(f"no results store at {str(run_dir)!r}: cells.parquet not found")
    return costs_of(cells, store.read_train(), stack_seeds, copied, recorded_stacks(store.read_manifest()))


def recorded_stacks(manifest: dict | None) -> dict[str, int]:
    """cell id -> the size of the last seed stack a run record of the manifest lists it in
    (``bench run`` records the stacks it forms; older runs recorded none)."""
    out: dict[str, int] = {}
    for record in (manifest or {}).get("runs", []):
        for stack in record.get("stacks") or []:
            out.update(dict.fromkeys(stack, len(stack)))
    return out


def costs_of(cells: pd.DataFrame, train: pd.DataFrame, stack_seeds: int = 1,
             copied: Iterable[str] = (), recorded: dict[str, int] | None = None) -> pd.DataFrame:
    """``observed_costs`` of a run's ``cells.parquet`` rows and training rows (``recorded``:
    the stacks its manifest lists, which take precedence over those ``stack_seeds`` forms)."""
    skip = set(copied)
    every = [Cell.model_validate_json(j) for j in cells["config_json"]]
    stacks = {**run_stacks(cells, every, stack_seeds, skip), **(recorded or {})}
    done = cells["status"] == "done"
    train_s = train[train["cell_id"].isin(cells.loc[done, "cell_id"])].groupby("cell_id")["wall_s"].sum()
    rows = []
    for r, cell in zip(cells.itertuples(index=False), every, strict=True):
        if r.status != "done":
            continue
        train_steps, eval_steps = costs.cell_agent_steps(cell)
        stack = stacks.get(r.cell_id, 1)
        t = float(train_s.get(r.cell_id, 0.0))
        e = float(r.wall_s) - t
        one_seed_t = t * costs.stack_gain(cell.method, cell.n_robots, stack)
        rows.append(dict(cell_id=r.cell_id, method=cell.method, n_robots=cell.n_robots, train_s=t, eval_s=e,
                         train_rate=train_steps / one_seed_t if train_steps and t > 0 else np.nan,
                         eval_rate=eval_steps / e if eval_steps and e > 0 else np.nan,
                         stack=stack, trained_here=r.cell_id not in skip))
    return pd.DataFrame(rows, columns=["cell_id", "method", "n_robots", "train_s", "eval_s",
                                       "train_rate", "eval_rate", "stack", "trained_here"])


def stacked_before_0237(cell: Cell) -> bool:
    """What ``bench run --stack-seeds K`` stacked before its runs recorded their stacks
    (docs/decisions/0237): the hierarchical method with per-group parameters only."""
    return cell.method == "hierarchical" and not cell.method_params().model_dump().get("share_params", False)


def run_stacks(cells: pd.DataFrame, every: list[Cell], stack_seeds: int,
               copied: set[str] | None = None) -> dict[str, int]:
    """cell id -> the size of the seed stack ``bench run --stack-seeds stack_seeds`` trained it
    in, formed over the run's cells (``every``: their parsed configs) but the ``copied`` ones,
    which another run trained and are left out, with the rule of the runs that did not record
    their stacks (``stacked_before_0237``)."""
    own = [i for i, cid in enumerate(cells["cell_id"]) if not copied or cid not in copied]
    return dict(zip(cells["cell_id"].iloc[own], costs.stack_sizes([every[i] for i in own], stack_seeds,
                                                                  stackable=stacked_before_0237), strict=True))


def estimate_vs_realized(cells: pd.DataFrame, stack_seeds: int = 1, rates: Rates | None = None,
                         exclude: Iterable[str] = ()) -> pd.DataFrame:
    """Per method, over the done cells of a run's ``cells.parquet`` rows but ``exclude``
    (e.g. cells copied in from another run): cells, the worker-hours ``bench grids``
    estimated for them (``rates``, default the built-in ones; stacks as ``bench run
    --stack-seeds stack_seeds`` forms them over all the run's cells) and the worker-hours
    they took (the sum of their ``wall_s``: a stacked cell's is its share of the stack),
    and realized / estimate; a last row ``all`` sums them."""
    every = [Cell.model_validate_json(j) for j in cells["config_json"]]
    stacks = run_stacks(cells, every, stack_seeds)
    skip = set(exclude)
    rows = []
    for r, cell in zip(cells.itertuples(index=False), every, strict=True):
        if r.status == "done" and r.cell_id not in skip:
            estimate = costs.cell_seconds(cell, rates, stacks[r.cell_id])
            rows.append({"method": cell.method, "estimated_h": estimate / 3600, "realized_h": float(r.wall_s) / 3600})
    frame = pd.DataFrame(rows, columns=["method", "estimated_h", "realized_h"])
    out = frame.groupby("method", sort=True).agg(cells=("method", "size"), estimated_h=("estimated_h", "sum"),
                                                 realized_h=("realized_h", "sum")).reset_index()
    total = pd.DataFrame([{"method": "all", "cells": len(frame), "estimated_h": frame["estimated_h"].sum(),
                           "realized_h": frame["realized_h"].sum()}])
    out = pd.concat([out, total], ignore_index=True) if len(out) else total
    return out.assign(ratio=out["realized_h"] / out["estimated_h"].where(out["estimated_h"] > 0))


def observed_rates(observed: pd.DataFrame) -> Rates:
    """Median effective rate per method, phase and N, in the layout of
    ``costs.AGENT_STEPS_PER_S`` (only the (method, phase, N) the run has), over the cells
    the run trained itself where it trained any at that (method, N), else over those
    copied in (a frame without ``trained_here``: all its cells)."""
    out: Rates = {}
    for (method, n), g in observed.groupby(["method", "n_robots"]):
        if "trained_here" in g and g["trained_here"].any():
            g = g[g["trained_here"]]
        for phase in ("train", "eval"):
            vals = g[f"{phase}_rate"].dropna()
            if len(vals):
                out.setdefault(str(method), {}).setdefault(phase, {})[int(n)] = float(vals.median())
    return out


def merged_rates(observed: Rates, base: Rates | None = None) -> Rates:
    """``base`` (default: the built-in rates) with each (method, phase) that ``observed``
    has replaced by the observed points: a run's rates where it measured them."""
    return costs.merge_rates(costs.AGENT_STEPS_PER_S if base is None else base, observed)


def two_digits(x: float) -> float:
    """``x`` rounded to 2 significant digits (the precision the rates deserve)."""
    return round(x, 1 - int(math.floor(math.log10(abs(x))))) if x else 0.0


def rates_file(observed: pd.DataFrame, run: str, stack_seeds: int = 1, copied_from: str | None = None) -> dict:
    """The content of ``bench/design/cost_rates.json`` for a run's observed costs (observed
    with ``stack_seeds`` and the cells of the run ``copied_from`` as copied, recorded so the
    file can be rebuilt)."""
    rates = observed_rates(observed)
    return {"run": run, "stack_seeds": stack_seeds, "copied_from": copied_from, "done_cells": int(len(observed)),
            "rates": {m: {ph: {str(n): two_digits(r) for n, r in sorted(pts.items())}
                          for ph, pts in sorted(phases.items())} for m, phases in sorted(rates.items())}}
