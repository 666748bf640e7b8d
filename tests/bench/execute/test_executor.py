"""One fault-injection suite run against both forms of the executor (bench/execute/executor.py):
a unit that raises, a worker killed mid-unit, a lost worker restarted, retries exhausted, and
results that do not depend on the form or the order. Runtime: ~40 s on 2 shared cores."""
from __future__ import annotations

import os
import signal
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from bench.execute.executor import (
    Done,
    Failed,
    InProcessExecutor,
    Outcome,
    RayExecutor,
    Retried,
    Unit,
    WorkerLost,
)
from tests.crash_once import first_claim


class Worker:
    """Pure units plus faults; ``calls`` counts the calls this process (or object) served."""

    def __init__(self) -> None:
        self.calls = 0

    def ping(self) -> int:
        return os.getpid()

    def square(self, x: int) -> int:
        self.calls += 1
        return x * x

    def served(self) -> int:
        self.calls += 1
        return self.calls

    def boom(self) -> None:
        raise ValueError("bad   unit\non two lines")

    def die_once(self, marker: str, x: int) -> int:
        """The worker dies (SIGKILL on Ray, WorkerLost in-process) the first time, anywhere."""
        if first_claim(marker):
            _die()
        return x * x

    def die(self) -> None:
        _die()


def _die() -> None:
    import ray

    if ray.is_initialized() and ray.get_runtime_context().get_actor_id() is not None:
        os.kill(os.getpid(), signal.SIGKILL)
    raise WorkerLost("killed")


@pytest.fixture(params=["in_process", "ray"])
def make(request: pytest.FixtureRequest) -> Iterator[Any]:
    made: list[Any] = []

    def build(capacity: int = 2) -> Any:
        if request.param == "in_process":
            ex: Any = InProcessExecutor(Worker, capacity)
        else:
            request.getfixturevalue("ray_local")
            ex = RayExecutor(Worker, capacity, max_restarts=1)
        made.append(ex)
        return ex

    yield build
    for ex in made:
        ex.close()


def _drain(ex: Any, n: int) -> list[Outcome]:
    """Outcomes until ``n`` units are settled (Done or Failed)."""
    out: list[Outcome] = []
    while sum(not isinstance(o, Retried) for o in out) < n:
        out.extend(ex.wait(5.0))
    return out


def test_executor__results_are_the_units_own_whatever_the_form_and_order(make: Any) -> None:
    ex = make()
    for x in range(7):
        ex.submit(Unit("square", (x,), key=x, tag=f"u{x}"))
    out = _drain(ex, 7)
    assert all(isinstance(o, Done) for o in out)
    assert sorted((o.unit.tag, o.result) for o in out) == sorted((f"u{x}", x * x) for x in range(7))


def test_executor__a_unit_that_raises_fails_alone_and_is_not_retried(make: Any) -> None:
    ex = make()
    ex.submit(Unit("boom", (), key="bad"))
    ex.submit(Unit("square", (3,), key="good"))
    out = {o.unit.key: o for o in _drain(ex, 2)}
    assert isinstance(out["bad"], Failed) and not out["bad"].lost
    assert out["bad"].message == "ValueError: bad unit on two lines"
    assert isinstance(out["good"], Done) and out["good"].result == 9


def test_executor__a_worker_killed_mid_unit_reruns_the_unit_elsewhere(make: Any, tmp_path: Path) -> None:
    ex = make()
    marker = str(tmp_path / "died")
    ex.submit(Unit("die_once", (marker, 4), key="k"))
    out = _drain(ex, 1)
    assert [type(o) for o in out] == [Retried, Done]
    assert out[-1].result == 16 and Path(marker).exists()


def test_executor__a_lost_worker_is_restarted_and_takes_work_again(make: Any) -> None:
    ex = make(capacity=1)
    ex.submit(Unit("served", (), key="a", sticky=True))
    first = _drain(ex, 1)[-1]
    assert isinstance(first, Done) and first.result == 1
    ex.submit(Unit("die", (), key="a", retries=0))  # its worker dies; not run again
    lost = _drain(ex, 1)[-1]
    assert isinstance(lost, Failed) and lost.lost and lost.message.startswith("worker died 1 time: ")
    ex.submit(Unit("served", (), key="b"))
    again = _drain(ex, 1)[-1]
    assert isinstance(again, Done) and again.result == 1  # a fresh worker: its count starts over


def test_executor__retries_exhausted_is_one_clear_failure_and_the_executor_goes_on(make: Any) -> None:
    ex = make()
    ex.submit(Unit("die", (), key="doomed", retries=2))
    out = _drain(ex, 1)
    assert [type(o) for o in out] == [Retried, Retried, Failed]
    assert out[-1].lost and out[-1].message.startswith("worker died 3 times: ")
    ex.submit(Unit("square", (5,), key="after"))
    assert _drain(ex, 1)[-1].result == 25


def test_executor__a_sticky_unit_keeps_its_worker_until_released(make: Any) -> None:
    ex = make()
    ex.submit(Unit("served", (), key="s", sticky=True))
    w = _drain(ex, 1)[-1].worker
    ex.submit(Unit("square", (2,), key="other"))
    assert _drain(ex, 1)[-1].worker != w  # reserved for "s"
    ex.submit(Unit("served", (), key="s", sticky=True))
    nxt = _drain(ex, 1)[-1]
    assert nxt.worker == w and nxt.result == 2  # the same worker, which counted the first call
    assert ex.free() == 1
    ex.release("s")
    assert ex.free() == 2
