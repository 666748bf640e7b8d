"""The observer interface of a run: what a logger (TensorBoard, MLflow, W&B, yours) sees.

The runner (the driver; workers never log) tells one ``RunObserver`` four things per cell,
in this order: ``on_cell_start`` (each time the cell starts or resumes in this run),
``on_train_rows`` (after every training chunk is stored: that chunk's rows, the same
values as ``train/``, plus the extra numbers a method reports per update such as
``entropy``, ``entropy_ref``, ``entropy_local`` or ``grad_norm``, which the store does not
keep), ``on_eval`` (once, when the cell's evaluation file is written: the mean of every
metric per execution mode) and ``on_cell_end`` (``done`` or ``failed``). Rows reach the
observer after they are stored, so a logger never shows a value the store does not hold.

A logger of your own is a class with these methods (subclass ``Observer`` to get no-op
defaults and override only what you need); ``bench.tracking.make_observer`` or
``run_grid(..., observer=...)`` plugs it in. A logger that raises is switched off with one
warning line: a tracking problem never fails a cell (``Observers``).
"""
from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, TextIO, runtime_checkable

Row = Mapping[str, Any]


@dataclass(frozen=True)
class CellInfo:
    """What an observer knows of a cell: its id (in the tracker run's name), method, grid and
    config (the cell's canonical JSON fields, method parameters resolved: the run's
    parameters), and how many episodes one update trains (rows per update)."""

    cell_id: str
    method: str
    grid: str
    config: dict[str, Any] = field(default_factory=dict)
    batch_episodes: int = 1
    label: str = ""

    def run_name(self) -> str:
        """The tracker run's name, readable in a run list: method, N, p and seed, then the
        cell id (what stays unique), e.g. 'hierarchical N=8 p=0.2 seed=0 3f2a9c1b7d4e'."""
        c = self.config
        parts = [self.method]
        for key, label in (("n_robots", "N"), ("loss_p", "p"), ("seed", "seed")):
            if key in c:
                value = c[key]
                parts.append(f"{label}={value:g}" if isinstance(value, float) else f"{label}={value}")
        return " ".join([*parts, self.cell_id])

    def folder_name(self) -> str:
        """``run_name`` as a portable folder name (TensorBoard lists runs by folder):
        'hierarchical_N8_p0.2_seed0_3f2a9c1b7d4e'."""
        text = self.run_name().replace("=", "").replace(" ", "_")
        return "".join(ch if ch.isalnum() or ch in "._-" else "-" for ch in text)


@runtime_checkable
class RunObserver(Protocol):
    """Receives a run's per-cell events from the driver (see the module docstring)."""

    def on_cell_start(self, cell: CellInfo) -> None: ...

    def on_train_rows(self, cell: CellInfo, rows: Sequence[Row]) -> None: ...

    def on_eval(self, cell: CellInfo, summary: Mapping[str, Mapping[str, float]]) -> None: ...

    def on_cell_end(self, cell: CellInfo, status: str, error: str) -> None: ...

    def close(self) -> None: ...


class Observer:
    """A ``RunObserver`` that does nothing: subclass it and override what you need."""

    def on_cell_start(self, cell: CellInfo) -> None:
        return None

    def on_train_rows(self, cell: CellInfo, rows: Sequence[Row]) -> None:
        return None

    def on_eval(self, cell: CellInfo, summary: Mapping[str, Mapping[str, float]]) -> None:
        return None

    def on_cell_end(self, cell: CellInfo, status: str, error: str) -> None:
        return None

    def close(self) -> None:
        return None


class Observers(Observer):
    """Fans every event out to several observers; one that raises is disabled with one
    warning line on ``stream`` (stderr) and the run goes on."""

    def __init__(self, observers: Sequence[RunObserver], stream: TextIO | None = None) -> None:
        self.observers = list(observers)
        self.stream = stream
        self.disabled: dict[int, str] = {}

    def _each(self, method: str, *args: Any) -> None:
        for k, obs in enumerate(self.observers):
            if k in self.disabled:
                continue
            try:
                getattr(obs, method)(*args)
            except Exception as exc:  # a logger's failure must not fail the cell
                why = f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}"
                self.disabled[k] = why
                print(f"bench: warning: logger {type(obs).__name__} failed in {method} ({why}); "
                      "it is switched off for the rest of the run", file=self.stream or sys.stderr)

    def on_cell_start(self, cell: CellInfo) -> None:
        self._each("on_cell_start", cell)

    def on_train_rows(self, cell: CellInfo, rows: Sequence[Row]) -> None:
        self._each("on_train_rows", cell, rows)

    def on_eval(self, cell: CellInfo, summary: Mapping[str, Mapping[str, float]]) -> None:
        self._each("on_eval", cell, summary)

    def on_cell_end(self, cell: CellInfo, status: str, error: str) -> None:
        self._each("on_cell_end", cell, status, error)

    def close(self) -> None:
        self._each("close")


# ----------------------------------------------------------- runner events
def cell_info(st: Any, grid: str) -> CellInfo:
    """The ``CellInfo`` of a runner ``CellState``."""
    import json

    c = st.cell
    config = json.loads(c.canonical_json())
    params = dict(st.spec.get("params", {}))
    config["params"] = params  # resolved: defaults filled in
    return CellInfo(cell_id=st.cell_id, method=c.method, grid=grid, config=config,
                    batch_episodes=max(1, int(params.get("batch_episodes", 1) or 1)), label=st.label())


def dispatch(observer: RunObserver, kind: str, st: Any, grid: str, rows: Sequence[Row] | None = None) -> None:
    """Turn one runner event (bench/execute/runner.py ``_emit``) into the observer's calls."""
    if st is None or kind not in ("started", "train_chunk", "done", "failed"):
        return
    info = cell_info(st, grid)
    if kind == "started":
        observer.on_cell_start(info)
    elif kind == "train_chunk" and rows:
        observer.on_train_rows(info, rows)
    elif kind == "done":
        observer.on_eval(info, eval_summary([r for chunk in st.eval_rows.values() for r in chunk
                                             if int(r["episode"]) < st.cell.eval_episodes]))
        observer.on_cell_end(info, "done", "")
    elif kind == "failed":
        observer.on_cell_end(info, "failed", st.error)


# ------------------------------------------------------------------ metrics
def numeric_items(row: Row) -> dict[str, float]:
    """The row's numbers (bools and ids left out), in key order."""
    out = {}
    for k, v in row.items():
        if k in ("episode", "cell_id") or isinstance(v, bool) or not isinstance(v, (int, float)):
            continue
        out[k] = float(v)
    return out


def update_metrics(rows: Sequence[Row], batch_episodes: int) -> list[tuple[int, dict[str, float]]]:
    """Per update: (episodes trained after it, metrics). A metric is the mean over the
    update's episode rows, NaN entries left out (a value every row shares, such as a loss,
    is that value exactly); a metric that is NaN in every row is omitted. Rows arrive in
    episode order, ``batch_episodes`` per update (docs/decisions/0164)."""
    out = []
    b = max(1, int(batch_episodes))
    for start in range(0, len(rows), b):
        group = rows[start:start + b]
        metrics: dict[str, list[float]] = {}
        for r in group:
            for k, v in numeric_items(r).items():
                metrics.setdefault(k, []).append(v)
        values = {}
        for k, vs in metrics.items():
            finite = [v for v in vs if not math.isnan(v)]
            if not finite:
                continue
            values[k] = finite[0] if all(v == finite[0] for v in finite) else math.fsum(finite) / len(finite)
        out.append((int(group[-1]["episode"]) + 1, values))
    return out


def eval_summary(rows: Sequence[Row]) -> dict[str, dict[str, float]]:
    """Mean of every metric per execution mode over a cell's evaluation rows (NaN left out;
    an all-NaN metric omitted), plus ``episodes``: the mode's episode count."""
    by_mode: dict[str, list[Row]] = {}
    for r in rows:
        by_mode.setdefault(str(r.get("execution", "argmax")), []).append(r)
    out = {}
    for mode, group in by_mode.items():
        values: dict[str, list[float]] = {}
        for r in group:
            for k, v in numeric_items(r).items():
                if not math.isnan(v):
                    values.setdefault(k, []).append(v)
        out[mode] = {k: math.fsum(vs) / len(vs) for k, vs in values.items()}
        out[mode]["episodes"] = float(len(group))
    return out
