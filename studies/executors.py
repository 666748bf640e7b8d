"""Trial segments on the one executor (bench/execute/executor.py): in this process (tests,
``bench tune --inline``) or on Ray actors (default).

The driver (studies/runner.py) owns the study; the executor only runs ``TrialWorker.step()``
calls and hands back their outcomes, through a small surface:

* ``start(key, spec)``: run the trial's first segment (on a free worker);
* ``advance(key)``: run its next segment (on the same worker, which holds the trial);
  ``stop(key)``: the trial is done or pruned, its worker is free again;
* ``wait(timeout)`` -> ``[(key, Segment | Failure)]``: finished segments (maybe none).

A worker (``TrialHost``, one per core) holds the trial it runs and builds its ``TrialWorker``
inside the first ``step()``, so a bad configuration is an ordinary failed segment, never a
dead actor. A trial keeps its state in its worker, so its units are never retried
(``retries=0``): a dead worker (process killed, node lost) is a ``Failure`` with
``crashed=True`` and the driver re-queues the trial.

May import: bench.execute (executor, ray_cluster), studies.objective.
"""
from __future__ import annotations

import os
import traceback
from dataclasses import dataclass
from typing import Any, cast

from bench.execute.executor import Done, Executor, Failed, InProcessExecutor, Retried, Unit
from bench.execute.executor import RayExecutor as RayPool
from envs.errors import BenchError
from studies.objective import Segment, TrialSpec, TrialWorker


@dataclass(frozen=True)
class Failure:
    """A segment that raised (``crashed``: the worker process itself died)."""

    message: str
    crashed: bool = False
    user_error: bool = False  # a BenchError: the study's configuration is wrong


Outcome = Segment | Failure


class TrialHost:
    """A worker that runs one trial at a time, segment by segment; errors come back as ``Failure``."""

    def __init__(self) -> None:
        self.key: int | None = None
        self.worker: TrialWorker | None = None

    def ping(self) -> int:
        return os.getpid()

    def step(self, key: int, spec: TrialSpec, first: bool) -> Outcome:
        if first:
            self.key, self.worker = key, None
        elif self.key != key:  # restarted since the last segment: the trial's state is gone
            return Failure("worker died: restarted between segments", crashed=True)
        try:
            if self.worker is None:
                self.worker = TrialWorker(spec)
            return self.worker.step()
        except BenchError as exc:
            return Failure(str(exc), user_error=True)
        except Exception as exc:
            last = traceback.format_exception(exc)[-1].strip()
            return Failure(f"{type(exc).__name__}: {exc}".strip() if str(exc) else last)


class TrialExecutor:
    """The trial surface (module docstring) over an executor of ``TrialHost`` workers."""

    def __init__(self, executor: Executor, context: Any = None) -> None:
        self.executor, self.context = executor, context
        self.capacity = executor.capacity
        self.specs: dict[int, TrialSpec] = {}

    def start(self, key: int, spec: TrialSpec) -> None:
        self.specs[key] = spec
        self._submit(key, True)

    def advance(self, key: int) -> None:
        self._submit(key, False)

    def _submit(self, key: int, first: bool) -> None:
        self.executor.submit(Unit("step", (key, self.specs[key], first), key, sticky=True, retries=0))

    def stop(self, key: int) -> None:
        self.specs.pop(key, None)
        self.executor.release(key)

    def wait(self, timeout: float | None = None) -> list[tuple[int, Outcome]]:
        out: list[tuple[int, Outcome]] = []
        for outcome in self.executor.wait(timeout):
            key = cast(int, outcome.unit.key)  # the trial number given to start()
            if isinstance(outcome, Done):
                out.append((key, outcome.result))
            elif isinstance(outcome, Failed):
                out.append((key, Failure(outcome.message, crashed=outcome.lost)))
            else:  # pragma: no cover - retries=0: never retried
                assert not isinstance(outcome, Retried)
        return out

    def close(self) -> None:
        for key in list(self.specs):
            self.stop(key)
        if isinstance(self.executor, RayPool):
            self.executor.close(keep=self.context is not None and not self.context.started_here)
        else:
            self.executor.close()
        if self.context is not None:
            self.context.shutdown()


class SequentialExecutor(TrialExecutor):
    """Segments in this process, round-robin over ``capacity`` concurrent trials."""

    def __init__(self, capacity: int = 1) -> None:
        super().__init__(InProcessExecutor(TrialHost, capacity))


class RayExecutor(TrialExecutor):
    """One Ray actor (1 CPU) per concurrent trial.

    Ray is started or joined as for ``bench run`` (bench/execute/ray_cluster.py: embedded on
    loopback by default, ``address`` or ``RAY_ADDRESS`` joins a cluster, an already
    initialized Ray is used as is). ``capacity`` defaults to the cluster's CPUs. The
    driver never blocks longer than ``wait(timeout)``, so it can refresh trial leases.
    """

    def __init__(self, capacity: int | None = None, address: str | None = None) -> None:
        from bench.execute.ray_cluster import connect

        context = connect(address, capacity)
        super().__init__(RayPool(TrialHost, max(1, int(capacity or context.cpus)), context), context)
