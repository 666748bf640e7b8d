"""The worker that runs cells: training chunks and evaluation chunks (a Ray actor).

The driver (bench/execute/runner.py) owns every file; a worker only computes. A training chunk
runs up to ``k`` ``Method.train_iteration()`` calls and returns the rows and the state
dict to checkpoint; the worker keeps the method in memory so the next chunk of the same
cell continues without reloading. When the cached method does not match (another cell, a
restarted process, a re-dispatch after a crash), it is rebuilt from the cell seed and the
given checkpoint state, which by the Method contract continues exactly as an
uninterrupted run. A worker made with a ``device`` (``bench run --device``) builds its
methods' networks there; checkpoints come back on the host (``Method.state_dict``).
An evaluation chunk loads the trained state (passed by reference, ``ray.put`` once by
the driver) and returns ``Method.evaluate(chunk, seed, execution)`` rows: one chunk in
one execution mode (the driver fans out every mode x chunk).

The class is plain Python (unit-testable without Ray); the runner wraps it with
``ray.remote``. One torch thread per worker, or the cell's own count (``spec["threads"]``,
``bench run --cell-threads K``), set before each unit: every unit of a cell, training and
evaluation, runs at the thread count the cell trained with.
"""
from __future__ import annotations

import copy
import inspect
import os
import resource
import sys
import time
from collections.abc import Mapping
from typing import Any

from algorithms.base import Method
from algorithms.common.device import CPU
from algorithms.registry import method_class
from bench.execute.torch_setup import passive_wait, prepare_torch, set_threads
from envs.config import EnvConfig
from envs.errors import BenchError


def reset_peak_rss() -> None:
    """Reset the process's peak-RSS counter (Linux: /proc/self/clear_refs), if possible."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
    except OSError:
        pass


def peak_rss_mb() -> float:
    """Peak resident set size of this process in MB since the last reset.

    Linux: VmHWM (reset by ``reset_peak_rss``); elsewhere ``resource.getrusage`` (lifetime
    peak of the worker process, an upper bound when it ran earlier cells).
    """
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / (1024.0 * 1024.0) if sys.platform == "darwin" else rss / 1024.0


def cell_threads(spec: Mapping[str, Any]) -> int:
    """The torch threads a cell runs at (``bench run --cell-threads``; absent: one)."""
    return int(spec.get("threads", 1))


def build_method(spec: Mapping[str, Any], device: str = CPU) -> Method:
    """A fresh method for a cell spec (see ``runner.cell_spec``), weights from its seed, its
    networks on ``device`` (an execution choice: the cell does not name it). BenchError for a
    method whose ``__init__`` takes no device, asked for another than the cpu."""
    cls = method_class(str(spec["method_path"]))
    prepare_torch(cell_threads(spec))  # before the method exists: the cell's threads, no dynamo import
    if device == CPU:
        return cls(EnvConfig(**spec["env"]), dict(spec["params"]), seed=int(spec["seed"]))
    if "device" not in inspect.signature(cls.__init__).parameters:
        raise BenchError(f"--device {device}: method {cls.name} takes no device (its __init__ has no device "
                         "argument, algorithms/base.py); run it on the cpu")
    return cls(EnvConfig(**spec["env"]), dict(spec["params"]), seed=int(spec["seed"]),
               device=device)


def _resolve(box: list[Any]) -> Any:
    """The state in a one-element list: an ObjectRef (fetched here) or the state itself."""
    if not box:
        return None
    item = box[0]
    try:
        import ray

        if isinstance(item, ray.ObjectRef):
            return ray.get(item)
    except ImportError:  # pragma: no cover
        pass
    return item


class CellWorker:
    """Computes chunks of cells; holds the methods of the cells it trains (one, or one
    seed stack) and one evaluation method."""

    def __init__(self, device: str = CPU, threads: int = 1) -> None:  # torch: set up by the first method built
        self.device = device  # the networks' (bench run --device); cpu: the default
        if threads > 1:  # bench run --cell-threads K: set before torch loads in this process
            passive_wait()
        self._train: dict[str, Method] | None = None  # cell id -> method held between chunks
        self._eval: tuple[str, Method, dict[str, Any]] | None = None

    def ping(self) -> int:
        return os.getpid()

    def train_chunk(self, spec: Mapping[str, Any], state_box: list[Any], iterations: int,
                    k: int) -> dict[str, Any]:
        """Up to ``k`` training iterations of the cell, starting after ``iterations`` updates.

        ``state_box`` holds the checkpoint state at ``iterations`` (empty at the start).
        Returns rows, the state dict after the chunk, counters, wall_s and peak_mem_mb.
        """
        return self.train_stack([spec], [state_box], [iterations], k)[0]

    def train_stack(self, specs: list[Mapping[str, Any]], state_boxes: list[list[Any]],
                    iterations: list[int], k: int) -> list[dict[str, Any]]:
        """``train_chunk`` for S cells at once; cells that differ only in their seed and whose
        method stacks (``Method.stackable``) train with their rollouts in one batch
        (algorithms/common/seed_stack.py: the same numbers as one by one). One result per cell,
        its ``wall_s`` its share of the chunk (rows' wall time)."""
        reset_peak_rss()
        start = time.perf_counter()
        cached = self._train or {}
        methods = [self._training_method(spec, box, it, cached)
                   for spec, box, it in zip(specs, state_boxes, iterations, strict=True)]
        set_threads(cell_threads(specs[0]))  # a stack: cells of one run and count (the runner's)
        self._train = None
        rows: dict[int, list[dict[str, Any]]] = {id(m): [] for m in methods}
        wall = dict.fromkeys(rows, 0.0)
        views: dict[tuple[int, ...], Method] = {}  # one stack view per set of live cells
        for _ in range(k):
            live = [m for m, spec in zip(methods, specs, strict=True)
                    if m.learned and m.episodes_done < int(spec["episodes"])]
            if not live:
                break
            t0 = time.perf_counter()
            if len(live) > 1 and type(live[0]).stackable(live[0].params.model_dump()):
                key = tuple(id(m) for m in live)
                if key not in views:
                    views[key] = type(live[0]).stack_view(live)
                from algorithms.common.seed_stack import train_stacked  # torch: loaded by a stacked method

                out = train_stacked(live, views[key])
            else:
                out = [m.train_iteration() for m in live]
            share = (time.perf_counter() - t0) / len(live)
            for m, new in zip(live, out, strict=True):
                rows[id(m)].extend(new)
                wall[id(m)] += share
        states = [copy.deepcopy(m.state_dict()) for m in methods]
        # Building, loading and copying states: shared alike by the cells of the chunk.
        overhead = (time.perf_counter() - start - sum(wall.values())) / len(methods)
        results, keep, peak = [], {}, peak_rss_mb()  # one process: one peak for the chunk
        for spec, m, state in zip(specs, methods, states, strict=True):
            finished = not m.learned or m.episodes_done >= int(spec["episodes"])
            if not finished:
                keep[str(spec["cell_id"])] = m
            results.append({
                "rows": rows[id(m)], "state": state, "iterations": m.iterations,
                "episodes_done": m.episodes_done, "finished": finished, "wall_s": wall[id(m)] + overhead,
                "peak_mem_mb": peak,
            })
        self._train = keep or None
        return results

    def _training_method(self, spec: Mapping[str, Any], state_box: list[Any], iterations: int,
                         cached: dict[str, Method]) -> Method:
        """The cell's method at ``iterations`` updates: the one this worker holds, else rebuilt
        from the cell seed and the given checkpoint state."""
        cell_id = str(spec["cell_id"])
        method = cached.get(cell_id)
        if method is not None and method.iterations == iterations:
            return method
        method = build_method(spec, self.device)
        state = _resolve(state_box)
        if state is not None:
            method.load_state_dict(state)
        if method.iterations != iterations:
            raise RuntimeError(
                f"checkpoint of cell {cell_id} is at iteration {method.iterations}, "
                f"the driver expected {iterations}"
            )
        return method

    def eval_chunk(self, spec: Mapping[str, Any], state_box: list[Any], chunk: int,
                   execution: str | None = None) -> dict[str, Any]:
        """Evaluation rows of chunk ``chunk`` of the cell from its trained state, in mode
        ``execution`` (default: argmax, or planner for a planner)."""
        reset_peak_rss()
        t0 = time.perf_counter()
        cell_id = str(spec["cell_id"])
        state = _resolve(state_box)
        if self._eval is None or self._eval[0] != cell_id:
            method = build_method(spec, self.device)
            self._eval = (cell_id, method, copy.deepcopy(method.state_dict()))
        _, method, initial = self._eval
        set_threads(cell_threads(spec))
        # Every chunk starts from the same state (RNG streams included), so the rows do not
        # depend on which chunks this worker ran before; no state: the untrained initialization.
        method.load_state_dict(state if state is not None else initial)
        rows = method.evaluate(chunk, int(spec["seed"]), execution)
        return {"rows": rows, "wall_s": time.perf_counter() - t0, "peak_mem_mb": peak_rss_mb()}
