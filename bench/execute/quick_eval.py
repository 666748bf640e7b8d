"""``bench eval``: evaluate one method in this process, from a checkpoint or untrained.

Runs the runner's evaluator code (``CellWorker.eval_chunk``) in this process, so the rows
equal the eval table's rows for the same cell, state and execution mode; no Ray, no files
written. By default every mode of the cell (argmax, sample, sample@T; planner for PIBT).
"""
from __future__ import annotations

import contextlib
import json
import math
import sys
from collections.abc import Mapping
from typing import Any

import numpy as np

from algorithms.common.episodes import EVAL_METRICS
from algorithms.common.execution import parse_execution
from algorithms.registry import is_builtin
from bench.design.cells import Cell
from bench.design.overrides import override_cell
from bench.execute.plan import cell_spec
from bench.execute.worker import CellWorker
from bench.store.checkpoints import load_checkpoint
from envs.errors import BenchError
from envs.layouts import preset_for

EVAL_COLUMNS = EVAL_METRICS  # the eval table's metric columns (bench/store/schema.py EVAL_SCHEMA)


def quick_eval(method: str | None = None, checkpoint: str | None = None, n_robots: int | None = None,
               loss_p: float | None = None, layout: str | None = None, episodes: int = 10,
               seed: int | None = None, horizon: int | None = None, groups: int | None = None,
               execution: str | None = None, device: str = "cpu", sets: Mapping[str, Any] | None = None,
               ) -> tuple[Cell, list[dict[str, Any]]]:
    """(the evaluated cell, one row per episode and execution mode, mode by mode). CLI values
    override the checkpoint's cell, and ``sets`` (``bench eval --set``: cell fields or
    ``params.NAME``, bench/design/overrides.py) override after them, e.g. a rule that acts at
    evaluation only (``params.fallback``); ``execution`` restricts the modes to one;
    ``device`` runs the networks there (``bench eval --device``)."""
    base: dict[str, Any] = {}
    state = None
    if checkpoint is not None:
        ckpt = load_checkpoint(checkpoint)
        base = json.loads(ckpt["cell"])
        state = ckpt["state"]
        if method is not None and method != base["method"]:
            raise BenchError(f"--method {method!r} does not match the checkpoint's method {base['method']!r}")
    elif method is None:
        raise BenchError("give --method (untrained initialization) or --checkpoint")
    overrides = dict(method=method, n_robots=n_robots, loss_p=loss_p, layout=layout, seed=seed,
                     horizon=horizon, groups=groups)
    spec = {**base, **{k: v for k, v in overrides.items() if v is not None}}
    spec.setdefault("n_robots", 20)
    spec.setdefault("loss_p", 0.2)
    if layout is None and n_robots is not None:
        spec["layout"] = preset_for(n_robots)  # a new team size gets its own preset
    spec.update(episodes=0, eval_episodes=episodes)
    cell = override_cell(Cell.make(**spec), sets or {})
    modes = cell.execution_modes() if execution is None else (
        parse_execution(execution, where="--execution").name,)
    worker = CellWorker(device)  # the runner's evaluator code path: same rows as the eval table
    box = [state] if state is not None else []
    rows: list[dict[str, Any]] = []
    try:
        with contextlib.redirect_stdout(sys.stderr):  # a method's prints never mix into --json (D14)
            for mode in modes:
                for chunk in range(math.ceil(episodes / cell.method_params().eval_chunk)):
                    rows.extend(worker.eval_chunk(cell_spec(cell), box, chunk, mode)["rows"])
    except BenchError:
        raise
    except Exception as exc:
        text = " ".join(str(exc).split())[:200]
        if state is not None and isinstance(exc, (KeyError, RuntimeError, ValueError)):
            raise BenchError(f"checkpoint {checkpoint!r} does not fit {cell.method} with these settings: "
                             f"{text}") from None
        if is_builtin(cell.method):
            raise  # a bug of this package: the traceback helps
        raise BenchError(f"method {cell.method}: {type(exc).__name__}: {text}") from None  # an outside method's
    return cell, [r for r in rows if int(r["episode"]) < episodes]


def summarize(rows: list[dict[str, Any]]) -> dict[str, dict[str, float]]:
    """Per execution mode (in the rows' order), the mean over episodes of every eval column
    (NaN-aware: NaN only if every episode is NaN)."""
    out: dict[str, dict[str, float]] = {}
    for mode in dict.fromkeys(str(r["execution"]) for r in rows):
        sel = [r for r in rows if r["execution"] == mode]
        means = {}
        for col in EVAL_COLUMNS:
            vals = np.array([float(r.get(col, math.nan)) for r in sel], dtype=np.float64)
            means[col] = float(np.nanmean(vals)) if np.isfinite(vals).any() else math.nan
        out[mode] = means
    return out
