"""Driver-side progress: cells done / running / failed and an ETA.

A rich live bar on a terminal; plain log lines (on stderr) when stderr is not a TTY or
``CI=true``: by default one line per finished or failed cell (and per retry or rerun) and a
summary line every ``QUIET_EVERY_S`` seconds (``QuietLogProgress``); ``bench run --verbose``
prints every event (a cell started, each training chunk and evaluation unit: ``LogProgress``).
The runner calls ``update(snapshot)`` after every event and about once a second;
``close()`` at the end.
"""
from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass
from typing import Protocol


@dataclass(frozen=True)
class Snapshot:
    total: int
    done: int
    running: int
    failed: int
    fraction: float  # cost-weighted fraction of the work finished, 0..1
    elapsed_s: float
    message: str = ""  # the last event, e.g. "done 3f2a... (hierarchical N=40 p=0.2)"
    # the runner event behind it: start, started, train_chunk, eval_chunk, done, failed, retry, rerun, tick
    kind: str = ""

    @property
    def eta_s(self) -> float | None:
        """Remaining seconds at the cost-weighted rate so far; None before any progress."""
        if self.fraction <= 0.0 or self.elapsed_s <= 0.0:
            return None
        return self.elapsed_s * (1.0 - self.fraction) / self.fraction

    def line(self) -> str:
        eta = self.eta_s
        eta_txt = "?" if eta is None else fmt_duration(eta)
        return (f"cells {self.done}/{self.total} done, {self.running} running, {self.failed} failed"
                f" | {100 * self.fraction:5.1f}% | elapsed {fmt_duration(self.elapsed_s)} | ETA {eta_txt}")


def fmt_duration(seconds: float) -> str:
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h}h{m:02d}m{s:02d}s" if h else (f"{m}m{s:02d}s" if m else f"{s}s")


class Progress(Protocol):
    def update(self, snap: Snapshot) -> None: ...

    def close(self) -> None: ...


class NullProgress:
    def update(self, snap: Snapshot) -> None:
        return None

    def close(self) -> None:
        return None


class LogProgress:
    """One line per event (and at most one every ``every_s`` seconds otherwise)."""

    def __init__(self, every_s: float = 30.0, stream=None) -> None:
        self.every_s = every_s
        self.stream = stream or sys.stderr
        self._last_t = 0.0
        self._last_key: tuple[int, int, int, str] | None = None

    def update(self, snap: Snapshot) -> None:
        key = (snap.done, snap.running, snap.failed, snap.message)
        now = time.monotonic()
        if (key == self._last_key or not snap.message) and now - self._last_t < self.every_s:
            return
        self._last_key, self._last_t = key, now
        stamp = time.strftime("%H:%M:%S")
        msg = f" | {snap.message}" if snap.message else ""
        print(f"[{stamp}] {snap.line()}{msg}", file=self.stream, flush=True)

    def close(self) -> None:
        return None


QUIET_EVERY_S = 300.0
QUIET_KINDS = frozenset({"done", "failed", "retry", "rerun"})  # the events a quiet log prints


class QuietLogProgress(LogProgress):
    """The log without a terminal: the first snapshot, one line per finished or failed cell
    (and per retry or rerun), and a summary every ``every_s`` seconds
    (docs/decisions/0169)."""

    def __init__(self, every_s: float = QUIET_EVERY_S, stream=None) -> None:
        super().__init__(every_s, stream)
        self._started = False

    def update(self, snap: Snapshot) -> None:
        now = time.monotonic()
        if snap.kind in QUIET_KINDS:
            line = f"{snap.line()} | {snap.message}"
        elif not self._started or now - self._last_t >= self.every_s:
            line = snap.line()
        else:
            return
        self._started, self._last_t = True, now
        print(f"[{time.strftime('%H:%M:%S')}] {line}", file=self.stream, flush=True)


class RichProgress:
    """A live rich bar on stderr."""

    def __init__(self) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        self._console = Console(stderr=True)
        self._bar = Progress(
            TextColumn("[bold]cells[/]"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
            TextColumn("{task.fields[counts]}"), TimeElapsedColumn(), TextColumn("ETA {task.fields[eta]}"),
            console=self._console, transient=False,
        )
        self._task = self._bar.add_task("cells", total=1000, counts="", eta="?")
        self._bar.start()

    def update(self, snap: Snapshot) -> None:
        eta = snap.eta_s
        counts = f"{snap.done}/{snap.total} done, {snap.running} running, {snap.failed} failed"
        self._bar.update(self._task, completed=int(1000 * snap.fraction), counts=counts,
                         eta="?" if eta is None else fmt_duration(eta))
        if snap.message and snap.message.startswith("failed"):
            self._bar.console.print(f"[red]{snap.message}[/]")

    def close(self) -> None:
        self._bar.stop()


def make_progress(verbose: bool = False) -> Progress:
    """Rich on an interactive terminal, plain lines on CI or when stderr is redirected:
    quiet ones unless ``verbose`` (every event)."""
    if os.environ.get("CI", "").lower() in ("1", "true", "yes") or not sys.stderr.isatty():
        return LogProgress() if verbose else QuietLogProgress()
    return RichProgress()
