"""SIGTERM handled like Ctrl-C by every bench command (SPEC 7: one line, exit 143).

Light on purpose (no Ray, no torch): bench/cli.py ``main`` installs the handler around
every command; bench/execute/ray_cluster.py ``connect`` puts it back after ``ray.init`` replaced it.
"""
from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any


class Terminated(KeyboardInterrupt):
    """SIGTERM to the driver: handled like Ctrl-C (checkpoints kept, rerun resumes), exit 143.

    Ray turns an exception raised by a signal handler inside ``ray.wait``/``ray.get`` into
    a plain KeyboardInterrupt, so ``sigterm_received()`` is what tells the two apart."""


_SIGTERM_RECEIVED: list[bool] = [False]


def sigterm_received() -> bool:
    return _SIGTERM_RECEIVED[0]


@contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """While active, SIGTERM raises ``Terminated`` in the main thread (replacing the handler
    ``ray.init`` installs, which exits mid-write with a crash dump)."""
    def handler(signum: int, frame: Any) -> None:
        _SIGTERM_RECEIVED[0] = True
        raise Terminated()

    handler.bench_stop = True  # type: ignore[attr-defined]  # bench/execute/ray_cluster.py connect keeps it

    try:
        old = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)
