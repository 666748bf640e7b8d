"""Progress of ``bench tune``: finished / requested trials, running ones, elapsed and ETA.

The driver (studies/runner.py) builds a ``TuneSnapshot`` after every finished trial; the
CLI appends its ``line()`` to each log line and, on a terminal, also drives a rich bar.
The ETA is the throughput of this run so far: elapsed / trials finished by this run x
trials still to finish (parallel workers are included in the measured throughput).
"""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass

from bench.execute.progress import fmt_duration


@dataclass(frozen=True)
class TuneSnapshot:
    requested: int  # finished trials the study should hold
    finished: int  # complete + pruned trials the study holds now
    finished_now: int  # of which finished by this run
    running: int  # trials this driver is running
    elapsed_s: float  # seconds since this run started

    @property
    def eta_s(self) -> float | None:
        """Seconds to go at this run's throughput; None before its first finished trial."""
        if self.finished_now <= 0 or self.elapsed_s <= 0.0:
            return None
        return self.elapsed_s / self.finished_now * max(self.requested - self.finished, 0)

    def line(self) -> str:
        eta = self.eta_s
        return (f"[{self.finished}/{self.requested} finished, {self.running} running, "
                f"elapsed {fmt_duration(self.elapsed_s)}, ETA {'?' if eta is None else fmt_duration(eta)}]")


class TuneBar:
    """A rich progress bar on stderr (only on an interactive terminal; see ``make_bar``)."""

    def __init__(self, requested: int) -> None:
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
        )

        self.progress = Progress(TextColumn("[bold]trials[/]"), BarColumn(), MofNCompleteColumn(),
                                 TextColumn("{task.fields[running]} running"), TimeElapsedColumn(),
                                 TextColumn("ETA {task.fields[eta]}"),
                                 console=Console(stderr=True), transient=False)
        self.task = self.progress.add_task("trials", total=requested, running=0, eta="?")
        self.progress.start()

    def update(self, snap: TuneSnapshot) -> None:
        eta = snap.eta_s
        self.progress.update(self.task, total=snap.requested, completed=snap.finished,
                             running=snap.running, eta="?" if eta is None else fmt_duration(eta))

    def log(self, message: str) -> None:
        self.progress.console.print(message, markup=False, highlight=False)

    def close(self) -> None:
        self.progress.stop()


def make_bar(requested: int) -> TuneBar | None:
    """A bar on an interactive stderr; None on CI or when stderr is redirected (the log
    lines carry the same counts and ETA)."""
    if os.environ.get("CI", "").lower() in ("1", "true", "yes") or not sys.stderr.isatty():
        return None
    return TuneBar(requested)
