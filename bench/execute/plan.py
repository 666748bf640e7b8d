"""Where each cell of a run stands, read from the store (resume planning; writes nothing).

A cell is *done* when its eval file exists (written once, after every chunk of every
execution mode), holds one row per evaluation episode and mode, and its training rows are
complete (bench/store/completeness.py; checked on every run). A done cell with missing rows is
evaluated again from its final checkpoint (training rows complete) or trained again from
the start (identical numbers: seeds come from the cell), and ``rerun`` says why. Otherwise
its checkpoint (if any) says how far training got; train parts beyond it are stale and
are discarded by the runner before the cell continues. Every file consulted is
validated here, before anything is written, so a corrupt or foreign store is refused
with a BenchError and left untouched.

A cell id hashes the cell's own fields and parameter *overrides*, not the method's
defaults; cells.parquet keeps the resolved parameters (``params_json``). When the code now
resolves other parameters for a cell that has stored results (a default changed since),
resuming would mix two configurations under one id: the run is refused, naming the cells
and fields, unless ``rerun_changed``, which trains those cells again from the start after
the runner moves their old files to ``superseded/`` (``RunStore.supersede``).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

from bench.design.cells import Cell
from bench.design.costs import cell_seconds
from bench.design.grids import Grid
from bench.store.completeness import cell_rows, expected_for_cell
from bench.store.run_store import RunStore, read_meta
from bench.store.schema import SCHEMA_VERSION
from envs.errors import BenchError


def cell_spec(cell: Cell) -> dict[str, Any]:
    """What a worker needs to build the cell's method: plain data only."""
    return {
        "cell_id": cell.cell_id,
        "method_path": cell.method_path(),
        "env": cell.to_env_config().model_dump(mode="json"),
        "params": cell.method_params().model_dump(mode="json"),
        "seed": cell.seed,
        "episodes": cell.episodes,
        "eval_episodes": cell.eval_episodes,
        "executions": list(cell.execution_modes()),
    }

EvalUnit = tuple[str, int]  # (execution mode, evaluation chunk): the unit of evaluation fan-out


@dataclass
class CellState:
    """Driver-side state of one cell during a run."""

    cell: Cell
    spec: dict[str, Any]
    config: dict[str, Any]  # config columns of cells.parquet
    n_chunks: int  # evaluation chunks per execution mode
    phase: str = "pending"  # pending | training | evaluating | done | failed
    iterations: int = 0  # training updates covered by the last checkpoint
    episodes_done: int = 0  # training episodes covered by the last checkpoint
    trained: bool = False  # training finished; evaluation next
    has_checkpoint: bool = False
    state_ref: Any = None  # ObjectRef of the last checkpoint state (set by the runner)
    eval_todo: list[EvalUnit] = field(default_factory=list)
    eval_rows: dict[EvalUnit, list[dict[str, Any]]] = field(default_factory=dict)
    wall_s: float = 0.0  # worker seconds of the attempt that produces the cell's results
    superseded_wall_s: float = 0.0  # worker seconds of earlier attempts whose results were discarded
    peak_mem_mb: float = float("nan")
    attempts: int = 0
    retries: int = 0  # worker deaths in this run
    error: str = ""
    rerun: str = ""  # why a stored cell runs again (rows incomplete, or its parameters changed)
    superseded: dict[str, Any] | None = None  # stored row of a cell run with other parameters
    versions_json: str = "{}"
    weight: float = 1.0  # estimated cost, for the ETA

    @property
    def cell_id(self) -> str:
        return self.cell.cell_id

    @property
    def modes(self) -> tuple[str, ...]:
        """The cell's execution modes, in order (argmax, sample, sample@T; or planner)."""
        return tuple(self.spec["executions"])

    def eval_units(self) -> list[EvalUnit]:
        """Every (mode, chunk) of the cell's evaluation, mode by mode."""
        return [(m, c) for m in self.modes for c in range(self.n_chunks)]

    @property
    def finished(self) -> bool:
        return self.phase in ("done", "failed")

    def progress(self) -> float:
        """Fraction 0..1 of this cell's estimated work that is finished."""
        if self.finished:
            return 1.0
        c = self.cell
        evals = c.eval_episodes * len(self.modes)
        train_w = c.episodes / max(c.episodes + evals, 1)
        train_f = 1.0 if self.trained or c.episodes == 0 else min(self.episodes_done / c.episodes, 1.0)
        eval_f = len(self.eval_rows) / max(self.n_chunks * len(self.modes), 1)
        return train_w * train_f + (1.0 - train_w) * eval_f

    def status(self) -> str:
        return {"training": "running", "evaluating": "running"}.get(self.phase, self.phase)

    def row(self, grid: str) -> dict[str, Any]:
        """This cell's row of cells.parquet."""
        return {
            **self.config, "grid": grid, "status": self.status(), "error": self.error,
            "train_episodes_done": self.episodes_done, "wall_s": self.wall_s,
            "superseded_wall_s": self.superseded_wall_s, "peak_mem_mb": self.peak_mem_mb, "attempts": self.attempts,
            "versions_json": self.versions_json, "schema_version": SCHEMA_VERSION,
        }

    def label(self) -> str:
        c = self.cell
        return f"{self.cell_id} ({c.method} N={c.n_robots} p={c.loss_p} seed={c.seed})"


def params_changes(stored_json: str, cell: Cell) -> list[str]:
    """'field: stored -> now' for every resolved parameter that differs between a stored
    ``params_json`` and what this code resolves for ``cell`` (empty: unchanged or unknown)."""
    if not stored_json:
        return []
    try:
        old = json.loads(stored_json)
    except json.JSONDecodeError:
        return []
    if not isinstance(old, dict):  # e.g. "nan" from a row written without parameters
        return []
    params = cell.method_params()
    now = params.model_dump(mode="json")  # as stored in params_json
    # A parameter its Params declares added later, absent from the stored row, is no change
    # while at its default: the cell ran its default behaviour (docs/decisions/0216).
    defaults = type(params).model_fields
    for key in set(params.added_later) - set(old):
        if now.get(key) == defaults[key].default:
            del now[key]
    return dict_changes(old, now)


def dict_changes(old: dict[str, Any], new: dict[str, Any]) -> list[str]:
    """'key: old -> new' (JSON values, '(absent)' for a missing key) for every key whose
    value differs, in key order."""
    missing = object()
    return [f"{k}: {json.dumps(old.get(k)) if k in old else '(absent)'} -> "
            f"{json.dumps(new.get(k)) if k in new else '(absent)'}"
            for k in sorted(set(old) | set(new)) if old.get(k, missing) != new.get(k, missing)]


def plan_run(store: RunStore, grid: Grid, fresh: bool, rerun_changed: bool = False,
             ) -> tuple[list[CellState], list[dict[str, Any]]]:
    """(states of the grid's cells, rows of other cells already in cells.parquet)."""
    old: dict[str, dict[str, Any]] = {}
    if not fresh and store.exists():
        store.read_manifest()
        df = store.read_cells()
        if df is not None:
            old = {str(r["cell_id"]): r for r in df.to_dict("records")}
    states, changed = [], []
    for cell in grid.cells:
        params = cell.method_params()
        st = CellState(cell=cell, spec=cell_spec(cell), config=cell.config_columns(),
                       n_chunks=math.ceil(cell.eval_episodes / params.eval_chunk),
                       weight=max(cell_seconds(cell), 1e-6))
        prev = old.get(cell.cell_id)
        if prev is not None:
            st.attempts = int(prev.get("attempts") or 0)
            st.versions_json = str(prev.get("versions_json") or "{}")
            st.wall_s = float(prev.get("wall_s") or 0.0)
            st.superseded_wall_s = float(prev.get("superseded_wall_s") or 0.0)
        diff = params_changes(str(prev.get("params_json") or ""), cell) if prev is not None else []
        if diff and not fresh and store.has_results(cell.cell_id):
            changed.append(f"{st.label()}: {', '.join(diff)}")
            st.superseded = prev
            _discard_attempt(st)
            st.rerun = (f"was stored with other method parameters ({'; '.join(diff)}); its files moved "
                        "to superseded/, training it again from the start")
        elif not fresh:
            _resume_state(store, st)
        states.append(st)
    if changed and not rerun_changed:
        shown = "; ".join(changed[:5]) + (f"; and {len(changed) - 5} more" if len(changed) > 5 else "")
        raise BenchError(
            f"{store.root}: {len(changed)} stored cell(s) were run with other method parameters than "
            f"this code resolves for them (a default changed since): {shown}. Resuming would mix "
            "both under one cell id. Pass --rerun-changed to train them again (their old files move "
            "to superseded/), or set the old values in a grid file's params (a new cell id)")
    ids = {s.cell_id for s in states}
    others = [r for cid, r in old.items() if cid not in ids]
    return states, others


def _discard_attempt(st: CellState) -> None:
    """The stored attempt's results are not kept (the cell trains again from the start): its
    worker seconds move to ``superseded_wall_s``, so ``wall_s`` counts only the attempt that
    produces the cell."""
    st.superseded_wall_s += st.wall_s
    st.wall_s = 0.0


def _resume_state(store: RunStore, st: CellState) -> None:
    for _, path in store.train_parts(st.cell_id):
        read_meta(path)  # a corrupt committed part is refused before anything is written
    meta = store.eval_meta(st.cell_id)
    ckpt = store.read_checkpoint(st.cell_id, st.cell.method)
    if ckpt is not None and ckpt.get("cell") != st.cell.canonical_json():
        path = store.ckpt_path(st.cell_id, st.cell.method)
        raise BenchError(f"checkpoint {str(path)!r} belongs to another cell config")
    if meta is not None:
        rows = cell_rows(store, st.cell_id, expected_for_cell(st.cell), st.modes, st.cell.eval_episodes)
        gap = rows.gap
        if not gap:
            st.phase, st.trained = "done", True
            st.wall_s = float(meta.get("wall_s", st.wall_s))
            st.peak_mem_mb = float(meta.get("peak_mem_mb", st.peak_mem_mb))
            st.attempts = int(meta.get("attempts", st.attempts))
            st.episodes_done = int(meta.get("train_episodes_done", st.episodes_done))
            st.eval_rows = {u: [] for u in st.eval_units()}
            return
        if rows.train_complete and ckpt is not None and ckpt.get("finished"):
            st.rerun = f"was done but {gap} stored; evaluating it again from its final checkpoint"
        else:
            st.rerun = f"was done but {gap} stored; training it again from the start"
            _discard_attempt(st)
            return  # no checkpoint use: the missing rows come from episodes before it
    if ckpt is not None:
        st.has_checkpoint = True
        st.iterations = int(ckpt["iterations"])
        st.episodes_done = int(ckpt["episodes_done"])
        st.trained = bool(ckpt["finished"])
        st.wall_s = float(ckpt.get("wall_s", 0.0))
        st.peak_mem_mb = float(ckpt.get("peak_mem_mb", float("nan")))
        st.attempts = max(st.attempts, int(ckpt.get("attempts", 0)))
        st.spec["threads"] = int(ckpt.get("cell_threads", 1))  # a cell keeps its count (docs/decisions/0242)


def versions() -> dict[str, str]:
    """Package, git and library versions recorded with every cell and in the manifest."""
    import platform

    import numpy
    import pandas
    import pyarrow
    import ray
    import torch

    from bench.about import git_commit, package_version

    return {
        "package": package_version(), "git": git_commit(), "python": platform.python_version(),
        "numpy": numpy.__version__, "torch": torch.__version__, "ray": ray.__version__,
        "pandas": pandas.__version__, "pyarrow": pyarrow.__version__,
    }


def machine() -> dict[str, Any]:
    """Where a run executed (recorded per run in the manifest): host, OS, CPU model and count."""
    import os
    import platform

    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            model = next((ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")), model)
    except OSError:
        pass
    return {"host": platform.node(), "os": platform.platform(terse=True), "arch": platform.machine(),
            "cpu": model, "cpus": os.cpu_count() or 0}


def versions_json() -> str:
    return json.dumps(versions(), sort_keys=True)
