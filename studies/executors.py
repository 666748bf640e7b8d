"""Where trial segments run: Ray actors (default) or inline, one segment at a time (tests).

The driver owns the study; an executor only runs ``TrialWorker.step()`` calls and hands
back their outcomes. Both executors have the same small surface:

* ``start(key, spec)``: create the trial's worker and run its first segment;
* ``advance(key)``: run the next segment; ``stop(key)``: drop the worker (pruned/done);
* ``wait(timeout)`` -> ``[(key, Segment | Failure)]``: finished segments (maybe none).

A worker is built inside its first ``step()`` (``LazyWorker``), so a bad configuration is
an ordinary failed segment, never a dead actor. A dead actor (worker process killed,
node lost) is a ``Failure`` with ``crashed=True``: the driver re-queues that trial.
"""
from __future__ import annotations

import traceback
from collections import deque
from dataclasses import dataclass
from typing import Any

from envs.errors import BenchError
from studies.objective import Segment, TrialSpec, TrialWorker


@dataclass(frozen=True)
class Failure:
    """A segment that raised (``crashed``: the worker process itself died)."""

    message: str
    crashed: bool = False
    user_error: bool = False  # a BenchError: the study's configuration is wrong


Outcome = Segment | Failure


class LazyWorker:
    """Builds its ``TrialWorker`` on the first ``step()``; errors come back as ``Failure``."""

    def __init__(self, spec: TrialSpec) -> None:
        self.spec = spec
        self.worker: TrialWorker | None = None

    def step(self) -> Outcome:
        try:
            if self.worker is None:
                self.worker = TrialWorker(self.spec)
            return self.worker.step()
        except BenchError as exc:
            return Failure(str(exc), user_error=True)
        except Exception as exc:
            last = traceback.format_exception(exc)[-1].strip()
            return Failure(f"{type(exc).__name__}: {exc}".strip() if str(exc) else last)


class SequentialExecutor:
    """Runs segments inline, round-robin over ``capacity`` concurrent trials."""

    def __init__(self, capacity: int = 1) -> None:
        self.capacity = max(1, int(capacity))
        self.workers: dict[int, LazyWorker] = {}
        self.queue: deque[int] = deque()

    def start(self, key: int, spec: TrialSpec) -> None:
        self.workers[key] = LazyWorker(spec)
        self.queue.append(key)

    def advance(self, key: int) -> None:
        self.queue.append(key)

    def stop(self, key: int) -> None:
        self.workers.pop(key, None)
        if key in self.queue:
            self.queue.remove(key)

    def wait(self, timeout: float | None = None) -> list[tuple[int, Outcome]]:
        if not self.queue:
            return []
        key = self.queue.popleft()
        return [(key, self.workers[key].step())]

    def close(self) -> None:
        self.workers.clear()
        self.queue.clear()


class RayExecutor:
    """One Ray actor (1 CPU) per running trial; segments are actor method calls.

    Ray is started or joined as for ``bench run`` (bench/execute/ray_cluster.py: embedded on
    loopback by default, ``address`` or ``RAY_ADDRESS`` joins a cluster, an already
    initialized Ray is used as is). ``capacity`` defaults to the cluster's CPUs. The
    driver never blocks longer than ``wait(timeout)``, so it can refresh trial leases.
    """

    def __init__(self, capacity: int | None = None, address: str | None = None) -> None:
        import ray

        from bench.execute.ray_cluster import connect

        self.ray = ray
        self.context = connect(address, capacity)
        self.capacity = max(1, int(capacity or self.context.cpus))
        self.actor_cls = ray.remote(num_cpus=1, max_restarts=0)(LazyWorker)
        self.actors: dict[int, Any] = {}
        self.pending: dict[Any, int] = {}  # object ref -> key

    def start(self, key: int, spec: TrialSpec) -> None:
        self.actors[key] = self.actor_cls.remote(spec)
        self.advance(key)

    def advance(self, key: int) -> None:
        self.pending[self.actors[key].step.remote()] = key

    def stop(self, key: int) -> None:
        actor = self.actors.pop(key, None)
        for ref in [r for r, k in self.pending.items() if k == key]:
            del self.pending[ref]
        if actor is not None:
            self.ray.kill(actor, no_restart=True)

    def wait(self, timeout: float | None = None) -> list[tuple[int, Outcome]]:
        if not self.pending:
            return []
        ready, _ = self.ray.wait(list(self.pending), num_returns=1, timeout=timeout)
        out = []
        for ref in ready:
            key = self.pending.pop(ref)
            try:
                out.append((key, self.ray.get(ref)))
            except self.ray.exceptions.RayActorError as exc:
                out.append((key, Failure(f"worker died: {str(exc).splitlines()[0]}", crashed=True)))
            except self.ray.exceptions.RayError as exc:
                out.append((key, Failure(f"ray error: {str(exc).splitlines()[0]}")))
        return out

    def close(self) -> None:
        for key in list(self.actors):
            self.stop(key)
        self.context.shutdown()
