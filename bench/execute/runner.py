"""Runs a grid on Ray and records it in the store (SPEC 4 "Execution on Ray", "Store").

The driver owns every file and nothing else; workers (bench/execute/worker.py, one Ray actor per
core, one torch thread each; ``cell_threads`` K: one actor per K cores, K threads) only compute. The loop:

1. plan (bench/execute/plan.py): read and validate the store, decide where each cell resumes;
   connect to Ray; only then write (discard stale train parts, manifest, cells.parquet);
2. dispatch: a free worker takes an evaluation unit (execution mode x chunk) of a trained
   cell first, else starts
   (or resumes from its checkpoint) the next cell; training is sticky: the worker that
   trains a cell gets its next chunk of ``checkpoint_every`` iterations;
3. collect (the executor waits with ``ray.wait`` and timeouts, never a blocking get): a training chunk's rows
   are written as a part, then its checkpoint; after the last chunk the final state is
   ``ray.put`` once and evaluation units (every chunk in every execution mode: argmax,
   sample, sample@T; planner for PIBT) fan out to every free worker; when all are in, the
   eval file (one row per episode and mode) is written once and the cell is done;
4. failures (bench/execute/executor.py, the policy every driver shares): a method that
   raises fails its cell (error recorded, the rest go on); a worker that dies (process
   killed, node removed) is restarted by Ray and its unit is re-dispatched from the last
   checkpoint to any worker, up to ``MAX_RETRIES`` times per unit; each retry of a
   training chunk counts as an attempt of its cells.

Dispatch, collection, health pings and restarts are the executor's (``RayExecutor``): this
module decides which unit comes next and writes what comes back.

Seeds come from the cell only and chunk boundaries from ``checkpoint_every``, so the
numbers do not depend on the number of workers or on the order of execution.
"""
from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from algorithms.registry import method_class
from bench.design.costs import AUTO, StackSeeds, auto_stacking, stack_pays
from bench.design.grids import Grid
from bench.design.overrides import check_resume_overrides
from bench.execute.executor import (
    WAIT_S,
    Failed,
    NoLiveWorkers,
    Outcome,
    RayExecutor,
    Retried,
    Unit,
)
from bench.execute.plan import CellState, machine, plan_run, versions, versions_json
from bench.execute.progress import NullProgress, Progress, Snapshot
from bench.execute.ray_cluster import RayContext, connect
from bench.execute.signals import Terminated, sigterm_as_interrupt, sigterm_received  # noqa: F401 (re-exported)
from bench.execute.worker import CellWorker
from bench.store.integrity import RUN_FLAG, Damage
from bench.store.run_store import RunStore
from bench.store.schema import SCHEMA_VERSION
from bench.tracking.observers import RunObserver, dispatch
from envs.atomic import DiskFull, is_disk_full
from envs.errors import BenchError


@dataclass
class RunSummary:
    out: Path
    total: int
    done: int
    failed: int
    wall_s: float
    failures: dict[str, str] = field(default_factory=dict)
    rerun: dict[str, str] = field(default_factory=dict)  # done cells run again: rows were incomplete
    repaired: list[str] = field(default_factory=list)  # damaged files moved aside by --repair


EventHook = Callable[[str, CellState], None]


def run_grid(grid: Grid, out: str | Path, *, address: str | None = None, workers: int | None = None,
             fresh: bool = False, checkpoint_every: int = 10, progress: Progress | None = None,
             on_event: EventHook | None = None, command: list[str] | None = None,
             rerun_changed: bool = False, stack_seeds: StackSeeds = 1, repair: bool = False,
             observer: RunObserver | None = None, overrides: dict[str, Any] | None = None,
             device: str = "cpu", cell_threads: int = 1) -> RunSummary:
    """Run (or resume) every cell of ``grid`` into the store at ``out``; see the module docstring.

    ``device`` (``bench run --device``): the torch device of the learned methods' networks in
    every worker, each worker asking Ray for an equal share of one accelerator; an execution
    choice, recorded in the manifest's run record (absent: cpu), never in a cell.

    ``cell_threads`` (``bench run --cell-threads``, docs/decisions/0242): the torch threads each
    cell started in this run trains and evaluates with, each worker asking Ray for as many
    CPUs. More than one changes a cell's numbers (deterministically, for that count), so a
    cell keeps the count it started with (its checkpoint's, absent: 1) whatever a resumed run
    asks, its count is recorded in its checkpoint and eval file (``cell_threads``, absent: 1)
    and the run record, and no seed stacks are formed (``stack_seeds`` auto runs the longest
    cells first, unstacked; a count above 1 is refused).

    ``stack_seeds`` (``bench run --stack-seeds``): train up to K cells that differ only in their
    seed in one worker (seed_stack), or ``"auto"`` (the command's default, docs/decisions/0237):
    the ``workers`` cells with the longest estimated training and evaluation left run first,
    each alone, and the others of stackable methods in stacks of up to 3 when there are more
    of them than workers (``costs.auto_stacking``). The numbers are the same either way; the
    manifest's run record says what was chosen (``stack_seeds``, ``stacks``).

    ``observer`` (bench/tracking/observers.py) receives each cell's start, stored training rows,
    evaluation summary and end, from the driver (loggers: ``bench run --log``). ``overrides``
    (``bench run --set/--axis``, bench/design/overrides.py) are recorded in the manifest; a
    resumed run must give the ones the directory was made with.

    Raises BenchError before writing anything when the store, the grid or the address is bad,
    or when a file of the grid's cells is damaged or misplaced (bench/store/integrity.py) and not
    ``repair``; with ``repair`` such files move to superseded/ and their cells are recomputed.
    """
    check_threads_and_stacking(cell_threads, stack_seeds)
    store = RunStore(out)
    store.check_writable(repair and not fresh)
    if fresh:
        store.check_fresh()
    lock = store.lock()
    try:
        if not fresh:
            check_resume_overrides(store.read_manifest(), overrides or {}, str(out))
        damage = [] if fresh else check_integrity(store, grid, repair)
        # Ray first when files are to be moved aside: a start that fails (D19) moves nothing
        early = connect(address, workers) if damage else None
        try:
            repaired = move_damaged(store, damage)
            states, others = plan_run(store, grid, fresh, rerun_changed)
        except BaseException:
            if early is not None:
                early.shutdown()
            raise
        if early is not None:
            ctx = early
        elif all(st.phase == "done" for st in states) and not fresh and not (address or os.environ.get("RAY_ADDRESS")):
            ctx = RayContext(False, "not needed (every cell done)", 1)  # nothing to run: no Ray
        else:
            ctx = connect(address, workers)
        try:
            if cell_threads > ctx.cpus and not all(st.phase == "done" for st in states):
                raise BenchError(f"--cell-threads {cell_threads}: more threads than the {ctx.cpus} CPUs of the "
                                 "Ray cluster (each worker asks Ray for one CPU per thread)")
            with sigterm_as_interrupt():
                if lock is None:  # a new run directory: create and lock it now that all checks passed
                    try:
                        store.root.mkdir(parents=True, exist_ok=True)
                    except OSError as exc:
                        if is_disk_full(exc):
                            raise DiskFull(store.root) from None
                        raise
                    lock = store.lock()
                run = _Run(grid, store, states, others, ctx, workers, fresh, max(1, checkpoint_every),
                           progress or NullProgress(), on_event, command or sys.argv, stack_seeds,
                           observer, overrides, device, cell_threads)
                summary = run.execute()
                summary.repaired = repaired
                return summary
        finally:
            ctx.shutdown()
    finally:
        if lock is not None:
            os.close(lock)


def check_threads_and_stacking(cell_threads: int, stack_seeds: StackSeeds) -> None:
    """BenchError when cells on more than one thread are asked to train seed-stacked: a stack's
    numbers equal its cells' alone only on one thread (docs/decisions/0242)."""
    if cell_threads > 1 and stack_seeds != AUTO and int(stack_seeds) > 1:
        raise BenchError(f"--stack-seeds {stack_seeds} with --cell-threads {cell_threads}: seed stacks train on "
                         "one thread only; give --stack-seeds 1 or auto (which then forms no stacks)")


def check_integrity(store: RunStore, grid: Grid, repair: bool) -> list[Damage]:
    """Damaged or misplaced files of the grid's cells (and cells.parquet): a BenchError naming
    the first, unless ``repair``, which returns them for ``move_damaged``. Reads only."""
    if not store.exists():
        return []
    from bench.store.integrity import find_damage

    damage = [d for d in find_damage(store, store.integrity(), {c.cell_id for c in grid.cells}, True)
              if not d.rel.startswith("matrix")]  # bench matrix --repair's
    if damage and not repair:
        more = f" ({len(damage) - 1} more damaged or misplaced file(s))" if len(damage) > 1 else ""
        raise BenchError(f"{store.root}: {damage[0].line()}{more}")
    return damage


def move_damaged(store: RunStore, damage: list[Damage]) -> list[str]:
    """Move ``damage`` to superseded/repair-<time>/ (bench/store/integrity.py ``move_aside``);
    one line per file moved."""
    from bench.store.integrity import move_aside

    stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    dest = move_aside(store, store.integrity(), damage, stamp)
    return [f"moved damaged {d.rel} to {dest.relative_to(store.root) / d.rel} ({d.why}); "
            + (f"recomputing cell {d.cell_id}" if d.cell_id else
               "cells.parquet is rebuilt from the cells' files" if d.rel == "cells.parquet" else
               "recomputing the cells whose files it held")
            for d in damage if dest is not None]


class _Run:
    def __init__(self, grid: Grid, store: RunStore, states: list[CellState], others: list[dict[str, Any]],
                 ctx: RayContext, workers: int | None, fresh: bool, k: int, progress: Progress,
                 on_event: EventHook | None, command: list[str], stack_seeds: StackSeeds = 1,
                 observer: RunObserver | None = None, overrides: dict[str, Any] | None = None,
                 device: str = "cpu", cell_threads: int = 1) -> None:
        self.grid, self.store, self.states, self.others = grid, store, states, others
        self.device = device  # the networks' (bench run --device)
        self.cell_threads = cell_threads  # of the cells started here (bench run --cell-threads)
        self.overrides = overrides if overrides and any(overrides.values()) else None
        self.ctx, self.fresh, self.k, self.progress = ctx, fresh, k, progress
        self.on_event, self.command, self.observer = on_event, command, observer
        slots = max(1, ctx.cpus // cell_threads)  # one worker per cell_threads CPUs
        self.n_workers = max(1, min(workers or slots, slots))
        self.stack_arg = stack_seeds  # as given (a count, or "auto")
        # cells differing only in their seed trained together, up to stack_seeds; cell id ->
        # rank of the cells that run first, each alone (auto: the critical path)
        self.stack_seeds, self.first = self._plan_stacking(stack_seeds)
        self.stacks: list[list[str]] = []  # the seed stacks this run formed (its run record)
        self.versions = versions_json()
        self.t0 = time.monotonic()
        self.start_progress = sum(s.progress() * s.weight for s in states)
        self.total_weight = sum(s.weight for s in states) or 1.0
        self.last_error = ""

    # ------------------------------------------------------------------ setup
    def _plan_stacking(self, stack_seeds: StackSeeds) -> tuple[int, dict[str, int]]:
        """(stack size, the cells that run first and alone by rank): a count as given; auto
        decided over the cells still to train, by their estimated seconds left."""
        if stack_seeds != AUTO:
            return max(1, int(stack_seeds)), {}
        todo = [s for s in self.states if s.phase == "pending" and not s.trained]
        solo, k = auto_stacking([s.weight * (1.0 - s.progress()) for s in todo],
                                [stack_pays(s.cell) for s in todo], self.n_workers)
        if self.cell_threads > 1:  # the longest first still; no stacks (check_threads_and_stacking)
            k = 1
        return k, {todo[i].cell_id: rank for rank, i in enumerate(solo)}

    def _prepare_store(self) -> None:
        store = self.store
        if self.fresh:
            store.wipe()
            store.checksums = None
        store.remove_temp_files()
        store.integrity().start_recording()  # every file written from here on is recorded
        stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")
        for st in self.states:
            if st.superseded is not None:  # run with other parameters: keep its files aside
                store.supersede(st.cell_id, st.superseded, stamp)
            if st.phase != "done":
                store.discard_parts_from(st.cell_id, st.episodes_done if st.has_checkpoint else 0)
        now = datetime.now(timezone.utc).isoformat(timespec="seconds")
        manifest = (None if self.fresh else store.read_manifest()) or {"created": now, "runs": []}
        v = versions()
        self.run_record: dict[str, Any] = {"grid": self.grid.name, "started": now, "command": self.command,
                           "git": v["git"], "machine": machine(), "workers": self.n_workers,
                           "cells_done_before": sum(s.phase == "done" for s in self.states),
                           RUN_FLAG: 1}  # checksums.json is kept by this bench (bench/store/integrity.py)
        if self.stack_arg != 1:  # bench run --stack-seeds (absent: 1, no stacking)
            self.run_record["stack_seeds"] = self.stack_arg
        if self.device != "cpu":  # bench run --device (absent: the cpu)
            self.run_record["device"] = self.device
        if self.cell_threads != 1:  # bench run --cell-threads (absent: 1)
            self.run_record["cell_threads"] = self.cell_threads
        if self.overrides is not None:  # bench run --set/--axis (absent: none)
            manifest["overrides"] = self.run_record["overrides"] = self.overrides
        runs = list(manifest.get("runs", []))[-49:] + [self.run_record]
        manifest.update({
            "schema_version": SCHEMA_VERSION, "package_version": v["package"], "git_sha": v["git"],
            "versions": v, "grid": self.grid.name, "command": self.command, "updated": now,
            "runs": runs, "ray": self.ctx.address, "workers": self.n_workers,
        })
        store.write_manifest(manifest)
        self._write_cells()

    def _close_run_record(self) -> None:
        """The manifest's entry of this run gets its end, wall time and cells finished
        (commit, machine and wall time of each part of a long run)."""
        manifest = self.store.read_manifest()
        runs = manifest.get("runs") if manifest else None
        if manifest is None or not runs or runs[-1].get("started") != self.run_record["started"]:
            return
        done = sum(s.phase == "done" for s in self.states)
        self.run_record.update({
            "ended": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "wall_s": round(time.monotonic() - self.t0, 1),
            "cells_done_in_run": done - self.run_record["cells_done_before"], "cells_done_after": done,
        })
        if self.stacks:  # cell ids trained seed-stacked together in this run
            self.run_record["stacks"] = self.stacks
        manifest["runs"][-1] = self.run_record
        self.store.write_manifest(manifest)

    def _write_cells(self) -> None:
        self.store.write_cells(self.others + [s.row(self.grid.name) for s in self.states])

    # ------------------------------------------------------------------- loop
    def execute(self) -> RunSummary:
        self._prepare_store()
        ex: RayExecutor | None = None
        if not all(s.finished for s in self.states):
            ex = RayExecutor(CellWorker, self.n_workers, self.ctx, **self._worker_options())
        self._emit("start", None)
        for st in self.states:  # said at once: an interrupted run never reaches the summary
            if st.rerun:
                self._emit("rerun", st)
        try:
            while ex is not None and not all(s.finished for s in self.states):
                while ex.free() and self._dispatch(ex):
                    pass
                try:
                    outcomes = ex.wait(WAIT_S)
                except NoLiveWorkers as exc:
                    self._fail_remaining(str(exc))
                    break
                for outcome in outcomes:
                    self._outcome(ex, outcome)
                self._emit("tick", None)
        finally:
            if ex is not None:
                ex.close(keep=not self.ctx.started_here)
            self._write_cells()
            self._close_run_record()
            self.progress.close()
        failed = {s.cell_id: s.error for s in self.states if s.phase == "failed"}
        return RunSummary(self.store.root, len(self.states), sum(s.phase == "done" for s in self.states),
                          len(failed), time.monotonic() - self.t0, failed,
                          {s.cell_id: s.rerun for s in self.states if s.rerun})

    def _worker_options(self) -> dict[str, Any]:
        """RayExecutor options beyond the defaults (the cpu, one thread): none for a default run."""
        options: dict[str, Any] = {}
        if self.device != "cpu":
            options.update(worker_args=(self.device,),
                           num_gpus=1 / self.n_workers if self.device.startswith("cuda") else 0)
        if self.cell_threads > 1:
            options.update(worker_args=(self.device, self.cell_threads), num_cpus=self.cell_threads)
        return options

    def _dispatch(self, ex: RayExecutor) -> bool:
        """Submit an evaluation chunk, else the next cell to train (False: nothing to do)."""
        for st in self.states:
            if st.phase == "evaluating" and st.eval_todo:
                mode, chunk = unit = st.eval_todo.pop(0)
                ex.submit(Unit("eval_chunk", (st.spec, [st.state_ref], chunk, mode), ("eval", st.cell_id),
                               tag=(st, unit)))
                return True
        pending = [s for s in self.states if s.phase == "pending"]
        if not pending:
            return False
        # resumed cells first, then (auto) the critical cells, longest first; else grid order
        st = min(pending, key=lambda s: (not s.has_checkpoint, self.first.get(s.cell_id, len(self.first))))
        if st.trained:  # trained before the interruption: evaluate now
            self._start(st)
            return True
        group = [st] + self._stack_mates(st, pending)
        if len(group) > 1:
            self.stacks.append([c.cell_id for c in group])
        for mate in group:
            self._start(mate)
        self._submit_train(ex, ("train", tuple(c.cell_id for c in group)), group)
        return True

    def _stack_mates(self, st: CellState, pending: list[CellState]) -> list[CellState]:
        """Up to ``stack_seeds - 1`` other pending, untrained cells that differ from ``st``
        only in their seed, when its method trains seed-stacked (``--stack-seeds``); none for
        or among the cells that run alone (``first``)."""
        if self.stack_seeds < 2 or st.cell_id in self.first or not (
                stack_pays(st.cell) if self.stack_arg == AUTO else _stackable(st.spec)):
            return []
        key = _stack_key(st.spec)
        return [s for s in pending if s is not st and not s.trained and s.cell_id not in self.first
                and _stack_key(s.spec) == key][: self.stack_seeds - 1]

    def _start(self, st: CellState) -> None:
        import ray

        st.attempts += 1
        if st.state_ref is None and st.has_checkpoint:
            ckpt = self.store.read_checkpoint(st.cell_id, st.cell.method)
            st.state_ref = ray.put(ckpt["state"]) if ckpt is not None else None
        st.spec.setdefault("threads", self.cell_threads)  # a resumed cell's: its checkpoint's (plan.py)
        st.versions_json = self.versions
        if st.trained:
            self._begin_eval(st)
        else:
            st.phase = "training"
        self._write_cells()
        self._emit("started", st)

    def _submit_train(self, ex: RayExecutor, key: tuple[str, tuple[str, ...]], group: list[CellState]) -> None:
        """The next training chunk of the cells of ``group`` (one cell, or a seed stack); sticky:
        the worker that holds their methods gets their next chunk."""
        boxes = [[st.state_ref] if st.state_ref is not None else [] for st in group]
        ex.submit(Unit("train_stack", ([st.spec for st in group], boxes, [st.iterations for st in group], self.k),
                       key, tag=group, sticky=True))

    def _begin_eval(self, st: CellState) -> None:
        st.phase, st.trained = "evaluating", True
        st.eval_todo = [u for u in st.eval_units() if u not in st.eval_rows]

    # --------------------------------------------------------------- results
    def _outcome(self, ex: RayExecutor, outcome: Outcome) -> None:
        unit = outcome.unit
        cells: list[CellState] = unit.tag if unit.call == "train_stack" else [unit.tag[0]]
        if isinstance(outcome, Retried):  # the worker died: the executor runs the unit again
            self.last_error = outcome.message
            for st in cells:
                if not st.finished:
                    if unit.call == "train_stack":  # resumes from st.state_ref, the last checkpoint
                        st.attempts += 1
                        self._write_cells()
                    self._emit("retry", st)
            return
        if isinstance(outcome, Failed):
            for st in cells:
                if not st.finished:
                    self._fail(st, outcome.message)
            return
        if unit.call == "train_stack":
            self._train_done(ex, unit.key, cells, outcome.result)
            return
        st, eval_unit = unit.tag
        if st.finished:
            return
        st.wall_s += float(outcome.result["wall_s"])
        st.peak_mem_mb = _nanmax(st.peak_mem_mb, float(outcome.result["peak_mem_mb"]))
        self._eval_done(st, eval_unit, outcome.result["rows"])

    def _train_done(self, ex: RayExecutor, key: Any, group: list[CellState],
                    results: list[dict[str, Any]]) -> None:
        """Store a training chunk of every cell of ``group``; the cells that are not finished
        get their next chunk on the same worker (which holds their methods)."""
        going = []
        for st, result in zip(group, results, strict=True):
            if st.finished:
                continue
            st.wall_s += float(result["wall_s"])
            st.peak_mem_mb = _nanmax(st.peak_mem_mb, float(result["peak_mem_mb"]))
            if self._train_chunk_done(st, result):
                going.append(st)
        if going:
            self._submit_train(ex, key, going)
        else:
            ex.release(key)

    def _train_chunk_done(self, st: CellState, result: dict[str, Any]) -> bool:
        """Write one cell's chunk (rows, then checkpoint); True while it has training left."""
        import ray

        rows = result["rows"]
        if rows:
            assert int(rows[0]["episode"]) == st.episodes_done, "train rows out of order"
            self.store.write_train_part(st.cell_id, st.episodes_done, rows)
        st.iterations, st.episodes_done = int(result["iterations"]), int(result["episodes_done"])
        self.store.write_checkpoint(st.cell_id, {
            "cell": st.cell.canonical_json(), "method": st.cell.method, "iterations": st.iterations,
            "episodes_done": st.episodes_done, "finished": bool(result["finished"]),
            "wall_s": st.wall_s, "peak_mem_mb": st.peak_mem_mb, "attempts": st.attempts,
            "state": result["state"], **_threads_record(st),
        })
        st.has_checkpoint = True
        st.state_ref = ray.put(result["state"])
        self._emit("train_chunk", st, rows)
        if result["finished"]:
            self._begin_eval(st)
            self._write_cells()
            return False
        return True

    def _eval_done(self, st: CellState, unit: tuple[str, int], rows: list[dict[str, Any]]) -> None:
        st.eval_rows[unit] = rows
        self._emit("eval_chunk", st)
        units = st.eval_units()
        if any(u not in st.eval_rows for u in units):
            return
        # Mode by mode, episode by episode; the last chunk may run past eval_episodes.
        all_rows = [r for u in units for r in st.eval_rows[u] if int(r["episode"]) < st.cell.eval_episodes]
        self.store.write_eval(st.cell_id, all_rows, {
            "wall_s": st.wall_s, "peak_mem_mb": st.peak_mem_mb, "attempts": st.attempts,
            "train_episodes_done": st.episodes_done, **_threads_record(st),
        })
        st.phase, st.state_ref = "done", None
        self._write_cells()
        self._emit("done", st)

    def _fail(self, st: CellState, error: str) -> None:
        st.phase, st.error, st.state_ref, st.eval_todo = "failed", error, None, []
        self._write_cells()
        self._emit("failed", st)

    def _fail_remaining(self, error: str) -> None:
        for st in self.states:
            if not st.finished:
                st.phase, st.error = "failed", error

    # --------------------------------------------------------------- progress
    def _emit(self, kind: str, st: CellState | None, rows: list[dict[str, Any]] | None = None) -> None:
        message = event_message(kind, st, self.last_error) if st is not None else ""
        if self.on_event is not None and st is not None:
            self.on_event(kind, st)
        if self.observer is not None:
            dispatch(self.observer, kind, st, self.grid.name, rows)
        done_w = sum(s.progress() * s.weight for s in self.states)
        left = self.total_weight - self.start_progress
        frac = (done_w - self.start_progress) / left if left > 1e-9 else 1.0
        snap = Snapshot(
            total=len(self.states), done=sum(s.phase == "done" for s in self.states),
            running=sum(s.phase in ("training", "evaluating") for s in self.states),
            failed=sum(s.phase == "failed" for s in self.states), fraction=min(max(frac, 0.0), 1.0),
            elapsed_s=time.monotonic() - self.t0, message=message, kind=kind,
        )
        self.progress.update(snap)


def event_message(kind: str, st: CellState, last_error: str = "") -> str:
    """The progress line's news for one event of cell ``st`` (printed once, with the event).

    A resumed cell says where it resumes; a training chunk says how far the cell is and
    that its checkpoint is written; an evaluation unit how many of the cell's units are in."""
    label = st.label()
    if kind == "started":
        if st.trained:
            return f"started {label}: evaluation"
        return f"started {label}" + (f" from episode {st.episodes_done}" if st.episodes_done else "")
    if kind == "train_chunk":
        return f"trained {label}: {st.episodes_done}/{st.cell.episodes} episodes, checkpoint written"
    if kind == "eval_chunk":
        return f"evaluated {label}: {len(st.eval_rows)}/{len(st.eval_units())} units"
    if kind == "failed":
        return f"failed {label}: {st.error}"
    if kind == "retry":
        return f"retry {label} after {last_error[:80]}"
    if kind == "rerun":
        return f"{label} {st.rerun}"
    return f"{kind} {label}"


def _stack_key(spec: dict[str, Any]) -> str:
    """Cells with equal keys differ only in their seed (and cell id) and train on as many threads."""
    return json.dumps({k: spec.get(k, 1) for k in ("method_path", "env", "params", "threads")}, sort_keys=True,
                      default=str)


def _threads_record(st: CellState) -> dict[str, int]:
    """``cell_threads`` of a cell's checkpoint and eval file: absent for one thread (the default,
    the files as before)."""
    threads = int(st.spec.get("threads", 1))
    return {"cell_threads": threads} if threads != 1 else {}


def _stackable(spec: dict[str, Any]) -> bool:
    return bool(method_class(str(spec["method_path"])).stackable(spec["params"]))


def _nanmax(a: float, b: float) -> float:
    if a != a:  # NaN: nothing measured yet
        return b
    return a if b != b else max(a, b)
