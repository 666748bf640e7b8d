"""The worker that runs cells: training chunks and evaluation chunks (a Ray actor).

The driver (bench/runner.py) owns every file; a worker only computes. A training chunk
runs up to ``k`` ``Method.train_iteration()`` calls and returns the rows and the state
dict to checkpoint; the worker keeps the method in memory so the next chunk of the same
cell continues without reloading. When the cached method does not match (another cell, a
restarted process, a re-dispatch after a crash), it is rebuilt from the cell seed and the
given checkpoint state, which by the Method contract continues exactly as an
uninterrupted run. An evaluation chunk loads the trained state (passed by reference,
``ray.put`` once by the driver) and returns ``Method.evaluate(chunk, seed, execution)``
rows: one chunk in one execution mode (the driver fans out every mode x chunk).

The class is plain Python (unit-testable without Ray); the runner wraps it with
``ray.remote``. One torch thread per worker.
"""
from __future__ import annotations

import copy
import importlib
import os
import resource
import sys
import time
from collections.abc import Mapping
from typing import Any

import torch

from algorithms.base import Method
from envs.config import EnvConfig


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


def build_method(spec: Mapping[str, Any]) -> Method:
    """A fresh method for a cell spec (see ``runner.cell_spec``), weights from its seed."""
    module, name = str(spec["method_path"]).split(":")
    cls = getattr(importlib.import_module(module), name)
    return cls(EnvConfig(**spec["env"]), dict(spec["params"]), seed=int(spec["seed"]))


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
    """Computes chunks of cells; holds at most one training and one evaluation method."""

    def __init__(self) -> None:
        torch.set_num_threads(1)
        self._train: tuple[str, Method] | None = None
        self._eval: tuple[str, Method, dict[str, Any]] | None = None

    def ping(self) -> int:
        return os.getpid()

    def train_chunk(self, spec: Mapping[str, Any], state_box: list[Any], iterations: int,
                    k: int) -> dict[str, Any]:
        """Up to ``k`` training iterations of the cell, starting after ``iterations`` updates.

        ``state_box`` holds the checkpoint state at ``iterations`` (empty at the start).
        Returns rows, the state dict after the chunk, counters, wall_s and peak_mem_mb.
        """
        reset_peak_rss()
        t0 = time.perf_counter()
        cell_id = str(spec["cell_id"])
        cached = self._train
        if cached is not None and cached[0] == cell_id and cached[1].iterations == iterations:
            method = cached[1]
        else:
            self._train = None
            method = build_method(spec)
            state = _resolve(state_box)
            if state is not None:
                method.load_state_dict(state)
            if method.iterations != iterations:
                raise RuntimeError(
                    f"checkpoint of cell {cell_id} is at iteration {method.iterations}, "
                    f"the driver expected {iterations}"
                )
        episodes = int(spec["episodes"])
        rows: list[dict[str, Any]] = []
        try:
            for _ in range(k):
                if not method.learned or method.episodes_done >= episodes:
                    break
                rows.extend(method.train_iteration())
        except BaseException:
            self._train = None
            raise
        finished = not method.learned or method.episodes_done >= episodes
        self._train = None if finished else (cell_id, method)
        return {
            "rows": rows,
            "state": copy.deepcopy(method.state_dict()),
            "iterations": method.iterations,
            "episodes_done": method.episodes_done,
            "finished": finished,
            "wall_s": time.perf_counter() - t0,
            "peak_mem_mb": peak_rss_mb(),
        }

    def eval_chunk(self, spec: Mapping[str, Any], state_box: list[Any], chunk: int,
                   execution: str | None = None) -> dict[str, Any]:
        """Evaluation rows of chunk ``chunk`` of the cell from its trained state, in mode
        ``execution`` (default: argmax, or planner for a planner)."""
        reset_peak_rss()
        t0 = time.perf_counter()
        cell_id = str(spec["cell_id"])
        state = _resolve(state_box)
        if self._eval is None or self._eval[0] != cell_id:
            method = build_method(spec)
            self._eval = (cell_id, method, copy.deepcopy(method.state_dict()))
        _, method, initial = self._eval
        # Every chunk starts from the same state (RNG streams included), so the rows do not
        # depend on which chunks this worker ran before; no state: the untrained initialization.
        method.load_state_dict(state if state is not None else initial)
        rows = method.evaluate(chunk, int(spec["seed"]), execution)
        return {"rows": rows, "wall_s": time.perf_counter() - t0, "peak_mem_mb": peak_rss_mb()}
