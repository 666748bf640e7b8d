"""Worker actors of a run: health state per worker, and reuse across runs.

Workers get work only after a health ping answered; a worker whose call failed is probed
again (Ray restarts it) or replaced. Worker actors outlive a run only in a Ray session the
runner did not start (tests, notebooks), so the next run there skips process start-up.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from bench.execute.plan import CellState


@dataclass
class Slot:
    """One worker actor and what it is doing."""

    actor: Any
    busy: bool = False
    healthy: bool = False  # True once a ping came back; work goes only to healthy workers
    pinging: bool = False
    suspect: bool = False  # a call failed and no ping has come back since
    next_ping: float = 0.0  # monotonic time of the next health probe
    sticky: list[CellState] | None = None  # the cells this worker is training (one, or a seed stack)


# Worker actors outlive a run only in a Ray session the runner did not start (tests,
# notebooks): the next run reuses them instead of paying process start-up and imports again.
_IDLE: dict[str, list[Any]] = {}


def _session() -> str:
    import ray

    ctx = ray.get_runtime_context()  # job ids restart at 1 in every new cluster: add the node
    return f"{ctx.get_node_id()}/{ctx.get_job_id()}"


def take_workers(remote: Any, n: int) -> list[Any]:
    idle = _IDLE.pop(_session(), [])
    _IDLE.clear()  # actors of an earlier Ray session are gone with it
    taken, rest = idle[:n], idle[n:]
    _kill(rest)
    return taken + [remote.remote() for _ in range(n - len(taken))]


def release_workers(slots: list[Slot], keep: bool) -> None:
    """Keep workers for the next run (if Ray outlives this run) unless a call to them failed."""
    kept = [s.actor for s in slots if keep and not s.suspect]
    _kill([s.actor for s in slots if s.actor not in kept])
    if kept:
        _IDLE[_session()] = kept


def _kill(actors: list[Any]) -> None:
    import ray

    for actor in actors:
        ray.kill(actor, no_restart=True)
