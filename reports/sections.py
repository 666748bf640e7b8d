"""Report sections that installed packages add after the generic report: the plug-in point.

The generic report (``reports.build``) shows every method of any run. A package adds its own
sections the way it adds a method: in the entry-point group
``warehouse_marl_bench.report_sections`` (``name = "module:Class"``), a class with no
constructor arguments that follows ``ReportSections``. For each run the report asks every
registered section whether it ``applies`` to the run, and appends what ``build`` returns,
after the generic entries, in the order the sections are installed. This package's paper
wing (``paper/``) registers the paper's figures, Table I, ablation and claims this way.

A section writes its files with ``reports.writers`` into ``ctx.out`` and returns
``SectionOutput``: a heading, the index entries of its files, and optionally a ``Front``
(what the index prints under the heading before the entries, e.g. the claims' verdicts).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import Protocol

import pandas as pd

from envs.errors import BenchError
from reports.data.store import Store
from reports.pages.index import Front, Part

__all__ = ["SECTIONS_ENTRY_POINT_GROUP", "Front", "ReportContext", "ReportSections", "SectionOutput",
           "registered_sections"]

SECTIONS_ENTRY_POINT_GROUP = "warehouse_marl_bench.report_sections"


@dataclass(frozen=True)
class ReportContext:
    """What a section may read: the run's store, the rows of each configuration's default
    variant (``train``, ``evals``, ``cells``; reports.data.variants), the folder it writes
    into and the report's options (``claims_at``: "paper" or "run")."""

    run_dir: Path
    out: Path
    store: Store
    train: pd.DataFrame
    evals: pd.DataFrame
    cells: pd.DataFrame
    options: Mapping[str, str] = field(default_factory=dict)

    @property
    def methods(self) -> set[str]:
        """Methods with a cell in the run (done or not)."""
        return set(map(str, self.store.cells["method"]))


SectionOutput = Part  # a section of the index: its heading, entries and optional front matter


class ReportSections(Protocol):
    """A package's report sections: whether they apply to a run, and building them."""

    def applies(self, ctx: ReportContext) -> bool: ...

    def build(self, ctx: ReportContext) -> SectionOutput: ...


@lru_cache(maxsize=1)
def _registered() -> tuple[tuple[str, Callable[[], ReportSections]], ...]:
    out: dict[str, Callable[[], ReportSections]] = {}
    for ep in metadata.entry_points(group=SECTIONS_ENTRY_POINT_GROUP):
        if ep.name in out:
            raise BenchError(f"report section {ep.name!r} is registered twice (entry point {ep.value!r})")
        out[ep.name] = ep.load()
    return tuple(out.items())


def registered_sections() -> list[ReportSections]:
    """One instance of every registered section class, in installation order."""
    return [make() for _, make in _registered()]
