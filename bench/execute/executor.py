"""The one executor: runs units of work on workers with one retry, restart, health and fan-out
policy, in an in-process form (``InProcessExecutor``) and a Ray form (``RayExecutor``).

A *unit* is one method call on a worker object (``CellWorker.train_stack``, ``eval_chunk``,
a tuning trial's segment); the driver (bench/execute/runner.py, bench/execute/matrix.py,
studies/runner.py) owns every file and decides what to run, the executor only runs it:

* ``submit(unit)`` queues a unit, FIFO; ``free()`` says how many more units would start now
  (drivers submit while it is positive, so the unit they pick last is the freshest choice);
* ``wait(timeout)`` starts queued units on free healthy workers and returns the outcomes
  that came back: ``Done`` (the result), ``Retried`` (the worker was lost and the unit is
  queued again) or ``Failed`` (the unit raised, or its worker was lost too often);
* ``release(key)`` ends a reservation and drops the key's queued units; ``close()``.

Policy (the same in both forms):

* **Fan-out**: one worker per core; a queued unit goes to the first free healthy worker.
* **Affinity**: a ``sticky`` unit reserves its worker for its ``key`` once done (the worker
  holds the cell's method, or the trial's state, in memory): the key's next unit runs there,
  and no other key's unit does, until ``release(key)`` or a failure.
* **Failures**: a unit that raises is ``Failed`` (``lost=False``), never retried: the error is
  the method's. A unit whose worker died (process killed, node removed, a lost object) is
  queued again at the front, to any worker, up to ``unit.retries`` times per key (``Retried``
  each time), then ``Failed`` with ``lost=True``; a call refused by a restarting worker
  counts as a death (calls go only to workers whose health ping answered, so a refusal
  means the worker died under the call). Units that hold state in their worker
  (trials) set ``retries=0``: never run again, their driver re-queues them its own way.
* **Restarts and health**: Ray restarts a dead actor (``max_restarts``); a worker whose
  call failed gets work again only after a health ping answered; a ping that finds the
  actor dead for good (``ActorDiedError``) replaces it. No live worker for
  ``STALL_TIMEOUT_S``: ``wait`` raises ``NoLiveWorkers``. A joined cluster's head is
  probed on every wait (``RayContext.check_head``). In-process, a worker "dies" by raising
  ``WorkerLost``; it is rebuilt, as Ray restarts an actor.

Ray primitives used as they are: ``ray.wait`` with a timeout (the driver never blocks in a
get), actor ``max_restarts``; ``max_task_retries`` stays 0 on purpose, so that each loss
reaches the driver (a run counts attempts and re-dispatches from the last checkpoint to
any worker, not only the restarted one). ``ray.util.ActorPool`` does not fit: it has no
affinity and no health state (docs/decisions/0189).

Worker actors outlive a run only in a Ray session the executor did not start (tests,
notebooks): the next executor of the same worker class reuses them.

May import: envs, bench.execute.ray_cluster (and Ray, lazily).
"""
from __future__ import annotations

import time
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any

from envs.errors import BenchError

MAX_RETRIES = 3  # worker deaths tolerated per unit key
MAX_RESTARTS = 4  # Ray restarts of one worker actor
STALL_TIMEOUT_S = 600.0  # no live worker for this long: NoLiveWorkers
WAIT_S = 1.0  # longest single ray.wait
PING_RETRY_S = 0.5  # probe interval of a restarting worker
ERROR_CHARS = 500


class WorkerLost(Exception):
    """Raised by an in-process worker to play a dead worker process (tests of the policy)."""


class NoLiveWorkers(BenchError):
    """No worker answered a health ping for ``STALL_TIMEOUT_S``."""


@dataclass(eq=False)
class Unit:
    """One call ``worker.<call>(*args)``; ``tag`` is the driver's, carried to the outcome."""

    call: str
    args: tuple[Any, ...]
    key: Hashable
    tag: Any = None
    sticky: bool = False
    retries: int = MAX_RETRIES


@dataclass(frozen=True)
class Done:
    unit: Unit
    result: Any
    worker: int


@dataclass(frozen=True)
class Retried:
    unit: Unit
    message: str


@dataclass(frozen=True)
class Failed:
    unit: Unit
    message: str
    lost: bool  # the worker died (too often); else the unit raised


Outcome = Done | Retried | Failed


def error_line(exc: BaseException) -> str:
    """'RuntimeError: what it said' on one line (the cause of a Ray task error)."""
    return f"{type(exc).__name__}: {' '.join(str(exc).split())[:ERROR_CHARS]}"


@dataclass
class _Worker:
    handle: Any
    busy: bool = False
    healthy: bool = True
    pinging: bool = False
    suspect: bool = False  # a call failed and no ping has come back since
    next_ping: float = 0.0


@dataclass
class _Policy:
    """Queue, reservations and loss counts: the part both forms share."""

    workers: list[_Worker]
    queue: list[Unit] = field(default_factory=list)
    reserved: dict[Hashable, int] = field(default_factory=dict)  # key -> worker index
    deaths: dict[Hashable, int] = field(default_factory=dict)

    def runnable(self) -> list[tuple[Unit, int]]:
        """Queued units that can start now, each with its worker, in queue order."""
        taken: set[int] = set()
        held = set(self.reserved.values())
        out = []
        for unit in self.queue:
            w = self.reserved.get(unit.key)
            if w is None:
                w = next((i for i, s in enumerate(self.workers)
                          if i not in taken and i not in held and s.healthy and not s.busy), None)
            elif w in taken or not self.workers[w].healthy or self.workers[w].busy:
                w = None
            if w is not None:
                taken.add(w)
                out.append((unit, w))
        return out

    def free(self) -> int:
        held = set(self.reserved.values())
        idle = sum(1 for i, s in enumerate(self.workers) if s.healthy and not s.busy and i not in held)
        return max(0, idle - sum(1 for u in self.queue if u.key not in self.reserved))

    def done(self, unit: Unit, w: int) -> None:
        if unit.sticky:
            self.reserved[unit.key] = w
        else:
            self.reserved.pop(unit.key, None)

    def failed(self, unit: Unit, message: str) -> Failed:
        self.reserved.pop(unit.key, None)
        return Failed(unit, message, lost=False)

    def lost(self, unit: Unit, exc_name: str, message: str) -> Outcome:
        """Queue the unit again (front, any worker) or give up (module docstring)."""
        self.reserved.pop(unit.key, None)
        self.deaths[unit.key] = n = self.deaths.get(unit.key, 0) + 1
        if n <= unit.retries:
            self.queue.insert(0, unit)
            return Retried(unit, message)
        return Failed(unit, f"worker died {n} time{'s' * (n != 1)}: {exc_name}", lost=True)

    def release(self, key: Hashable) -> int:
        """End ``key``'s reservation; drop its queued units (returns how many)."""
        self.reserved.pop(key, None)
        kept = [u for u in self.queue if u.key != key]
        dropped = len(self.queue) - len(kept)
        self.queue = kept
        return dropped


class InProcessExecutor:
    """``capacity`` worker objects in this process; ``wait`` runs one queued unit."""

    def __init__(self, make_worker: Callable[[], Any], capacity: int = 1) -> None:
        self.make_worker = make_worker
        self.capacity = max(1, int(capacity))
        self.policy = _Policy([_Worker(make_worker()) for _ in range(self.capacity)])

    def submit(self, unit: Unit) -> None:
        self.policy.queue.append(unit)

    def free(self) -> int:
        return self.policy.free()

    def release(self, key: Hashable) -> int:
        return self.policy.release(key)

    def pending(self) -> bool:
        return bool(self.policy.queue)

    def wait(self, timeout: float | None = None) -> list[Outcome]:
        runnable = self.policy.runnable()
        if not runnable:
            return []
        unit, w = runnable[0]
        self.policy.queue.remove(unit)
        worker = self.policy.workers[w]
        try:
            result = getattr(worker.handle, unit.call)(*unit.args)
        except WorkerLost as exc:
            worker.handle = self.make_worker()  # a new process, as Ray restarts an actor
            return [self.policy.lost(unit, "WorkerLost", error_line(exc))]
        except Exception as exc:
            return [self.policy.failed(unit, error_line(exc))]
        self.policy.done(unit, w)
        return [Done(unit, result, w)]

    def close(self) -> None:
        self.policy.queue.clear()
        self.policy.reserved.clear()


# Worker actors outlive an executor only in a Ray session it did not start (tests,
# notebooks): the next one of the same worker class reuses them instead of paying process
# start-up and imports again. Keyed by (session, worker class and options). Actors of more
# than one CPU each (``num_cpus``) are not kept past an executor with other options: they
# would hold the CPUs its actors wait for.
_IDLE: dict[tuple[str, str], list[Any]] = {}


def _session() -> str:
    import ray

    ctx = ray.get_runtime_context()  # job ids restart at 1 in every new cluster: add the node
    return f"{ctx.get_node_id()}/{ctx.get_job_id()}"


def _kill(actors: list[Any]) -> None:
    import ray

    for actor in actors:
        ray.kill(actor, no_restart=True)


class RayExecutor:
    """``capacity`` Ray actors of ``worker_cls`` (``num_cpus`` CPUs each, default 1) on the cluster
    of ``ctx`` (bench/execute/ray_cluster.py ``connect``; the caller shuts it down)."""

    def __init__(self, worker_cls: type, capacity: int, ctx: Any = None, *,
                 max_restarts: int = MAX_RESTARTS, worker_args: tuple[Any, ...] = (), num_gpus: float = 0,
                 num_cpus: int = 1) -> None:
        import ray

        self.ray, self.ctx = ray, ctx
        self.capacity = max(1, int(capacity))
        # num_gpus > 0 (a share of an accelerator per worker): Ray hides the GPUs from actors that ask for none
        self.remote: Any = ray.remote(num_cpus=num_cpus, num_gpus=num_gpus, max_restarts=max_restarts,
                                      max_task_retries=0)(worker_cls)
        self.worker_args = worker_args
        self.pool_key = (_session(), f"{worker_cls.__module__}.{worker_cls.__qualname__}/{max_restarts}"
                         + (f"/{worker_args!r}/{num_gpus}" if worker_args or num_gpus else "")
                         + (f"/cpus={num_cpus}" if num_cpus != 1 else ""))
        idle = _IDLE.pop(self.pool_key, [])
        for key in [k for k in _IDLE if k[0] != self.pool_key[0]]:  # gone with their session
            del _IDLE[key]
        for key in [k for k in _IDLE if "/cpus=" in k[1] or "/cpus=" in self.pool_key[1]]:
            _kill(_IDLE.pop(key))  # idle actors of several CPUs, or new ones: free the CPUs for the new actors
        handles = idle[: self.capacity] + [self.remote.remote(*worker_args)
                                           for _ in range(self.capacity - len(idle[: self.capacity]))]
        _kill(idle[self.capacity:])
        # Reused actors are known healthy; new ones get work once a ping answered.
        self.policy = _Policy([_Worker(h, healthy=i < len(idle)) for i, h in enumerate(handles)])
        self.inflight: dict[Any, tuple[int, Unit | None]] = {}  # ref -> worker, unit (None: ping)
        self.stalled_since: float | None = None

    def submit(self, unit: Unit) -> None:
        self.policy.queue.append(unit)

    def free(self) -> int:
        return self.policy.free()

    def release(self, key: Hashable) -> int:
        return self.policy.release(key)

    def pending(self) -> bool:
        return bool(self.policy.queue) or any(u is not None for _, u in self.inflight.values())

    def wait(self, timeout: float | None = None) -> list[Outcome]:
        """Outcomes that came back within ``timeout`` seconds (None: until one does)."""
        end = None if timeout is None else time.monotonic() + timeout
        while True:
            self._start()
            out: list[Outcome] = []
            if self.inflight:
                left = WAIT_S if end is None else max(0.0, min(WAIT_S, end - time.monotonic()))
                ready, _ = self.ray.wait(list(self.inflight), num_returns=1, timeout=left)
                if ready:
                    more, _ = self.ray.wait(list(self.inflight), num_returns=len(self.inflight), timeout=0)
                    for ref in dict.fromkeys(ready + more):
                        out.extend(self._collect(ref))
            else:
                time.sleep(0.05)  # nothing running: every worker waits for its next health probe
            if self.ctx is not None:
                self.ctx.check_head()
            if out or not self.pending() or (end is not None and time.monotonic() >= end):
                return out

    def _start(self) -> None:
        now = time.monotonic()
        for unit, w in self.policy.runnable():
            self.policy.queue.remove(unit)
            worker = self.policy.workers[w]
            worker.busy = True
            self.inflight[getattr(worker.handle, unit.call).remote(*unit.args)] = (w, unit)
        for w, worker in enumerate(self.policy.workers):
            if not worker.healthy and not worker.pinging and now >= worker.next_ping:
                worker.pinging = True
                self.inflight[worker.handle.ping.remote()] = (w, None)
        if any(s.healthy for s in self.policy.workers) or not self.pending():
            self.stalled_since = None
            return
        self.stalled_since = self.stalled_since or now
        if now - self.stalled_since > STALL_TIMEOUT_S:
            raise NoLiveWorkers(f"no live Ray worker for {STALL_TIMEOUT_S:.0f} s")

    def _collect(self, ref: Any) -> list[Outcome]:
        ray = self.ray
        w, unit = self.inflight.pop(ref)
        worker = self.policy.workers[w]
        try:
            result = ray.get(ref, timeout=0)
        except ray.exceptions.RayTaskError as exc:  # the call raised: the unit fails
            cause = exc.cause if getattr(exc, "cause", None) is not None else exc
            if isinstance(cause, ray.exceptions.RayError) and not isinstance(cause, ray.exceptions.RayTaskError):
                return self._lost(w, unit, cause)  # e.g. a lost state object
            worker.busy = False
            return [] if unit is None else [self.policy.failed(unit, error_line(cause))]
        except ray.exceptions.RayError as exc:  # the worker died
            return self._lost(w, unit, exc)
        if unit is None:  # a ping answered
            worker.healthy, worker.pinging, worker.suspect = True, False, False
            return []
        worker.busy = False
        self.policy.done(unit, w)
        return [Done(unit, result, w)]

    def _lost(self, w: int, unit: Unit | None, exc: BaseException) -> list[Outcome]:
        """Re-queue the unit; probe the worker (Ray restarts it) or replace it if it is gone."""
        ray = self.ray
        worker = self.policy.workers[w]
        if unit is None:  # the ping failed
            worker.pinging, worker.suspect = False, True
            if isinstance(exc, ray.exceptions.ActorDiedError):  # restarts exhausted or node gone
                ray.kill(worker.handle, no_restart=True)
                worker.handle = self.remote.remote(*self.worker_args)
            else:  # restarting (ActorUnavailableError): probe again shortly
                worker.next_ping = time.monotonic() + PING_RETRY_S
            return []
        worker.busy, worker.healthy, worker.suspect, worker.next_ping = False, False, True, time.monotonic()
        return [self.policy.lost(unit, type(exc).__name__, f"{type(exc).__name__}: "
                                 f"{' '.join(str(exc).split())[:300]}")]

    def close(self, keep: bool = False) -> None:
        """Kill the workers, or with ``keep`` leave the healthy ones for the next executor."""
        if self.ctx is not None and getattr(self.ctx, "lost", False):
            return  # a lost cluster has no workers left to release
        workers = self.policy.workers
        kept = [s.handle for s in workers if keep and not s.suspect and not s.busy]
        _kill([s.handle for s in workers if s.handle not in kept])
        if kept:
            _IDLE[self.pool_key] = kept
        self.policy.queue.clear()
        self.inflight.clear()


Executor = InProcessExecutor | RayExecutor
