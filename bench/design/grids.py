"""Named grids of cells: ``smoke`` and ``lifelong`` (CI: lifelong tasks with and without
message delay) here, and every grid an installed package registers.

A grid is a deduplicated, ordered tuple of cells. ``--seeds K`` replicates every
configuration over seeds 0..K-1; a named grid's default seed count is its builder's
``seeds`` default (``smoke`` 1). Packages register named grids in the entry-point group
``warehouse_marl_bench.grids`` (``name = "module:builder"``, a function of ``seeds``
returning a ``Grid``), the way methods register; this package's paper wing registers
``paper``, ``full`` and ``ablation`` so. User grids come from TOML/YAML files
(bench/design/grid_files.py).
"""
from __future__ import annotations

import inspect
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from functools import lru_cache
from importlib import metadata
from typing import Any

from algorithms.registry import method_class
from bench.design.cells import Cell
from envs.errors import BenchError

ALL_METHODS = ("hierarchical", "decentralized", "ic3net", "pibt")  # the built-ins the CI grids run


@dataclass(frozen=True)
class Grid:
    name: str
    description: str
    cells: tuple[Cell, ...]

    def __len__(self) -> int:
        return len(self.cells)

    @property
    def methods(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(c.method for c in self.cells))

    @property
    def seeds(self) -> int:
        """Distinct seeds of the grid."""
        return len({c.seed for c in self.cells})

    @property
    def configurations(self) -> int:
        """Distinct cells once the seed is ignored (each runs ``seeds`` times)."""
        return len({c.model_copy(update={"seed": 0}).canonical_json() for c in self.cells})


def dedup(cells: Iterable[Cell]) -> tuple[Cell, ...]:
    """Cells in first-seen order, each cell_id once."""
    return tuple({c.cell_id: c for c in cells}.values())


def replicate(specs: Iterable[dict[str, Any]], seeds: int) -> tuple[Cell, ...]:
    """One cell per spec and seed 0..seeds-1, each cell_id once."""
    return dedup(Cell.make(**spec, seed=s) for spec in specs for s in range(seeds))


def planner_settings(spec: dict[str, Any]) -> dict[str, Any]:
    """A planner (``Method.learned`` False, e.g. PIBT) learns nothing: no training episodes."""
    return spec if method_class(spec["method"]).learned else {**spec, "episodes": 0}


def smoke(seeds: int = 1) -> Grid:
    """Every method at N in {8 (tiny), 16 (wh20)} x p in {0.2, 0.6}; tiny budgets (CI)."""
    specs = [
        planner_settings(dict(
            method=m, n_robots=n, layout=layout, loss_p=p, episodes=16, horizon=48,
            eval_episodes=10, params={"batch_episodes": 8, "eval_chunk": 5},
        ))
        for m in ALL_METHODS for n, layout in ((8, "tiny"), (16, "wh20")) for p in (0.2, 0.6)
    ]
    return Grid("smoke", "CI: every method, N in {8,16}, p in {0.2,0.6}, tiny budgets",
                replicate(specs, seeds))


def lifelong(seeds: int = 1) -> Grid:
    """Lifelong tasks (beyond the paper): every method at N=8 (tiny), p=0.2, with no delay
    and a fixed 2-step delay; smoke budgets (CI runs it end to end)."""
    specs = [
        planner_settings(dict(
            method=m, n_robots=8, layout="tiny", loss_p=0.2, task="lifelong", delay=d, episodes=16,
            horizon=48, eval_episodes=10, params={"batch_episodes": 8, "eval_chunk": 5},
        ))
        for m in ALL_METHODS for d in (0, 2)
    ]
    return Grid("lifelong", "CI: every method, lifelong tasks, N=8, p=0.2, delay 0 and 2, tiny budgets",
                replicate(specs, seeds))


GRID_ENTRY_POINT_GROUP = "warehouse_marl_bench.grids"  # where an installed package registers a named grid


@lru_cache(maxsize=1)
def grid_builders() -> dict[str, Callable[..., Grid]]:
    """Named grids: ``smoke``, ``lifelong`` and every builder of entry-point group
    ``warehouse_marl_bench.grids``, in the order they are installed."""
    out: dict[str, Callable[..., Grid]] = {"smoke": smoke, "lifelong": lifelong}
    for ep in metadata.entry_points(group=GRID_ENTRY_POINT_GROUP):
        if ep.name in out:
            raise BenchError(f"grid {ep.name!r} is registered twice (entry point {ep.value!r})")
        out[ep.name] = ep.load()
    return out


def default_seeds(name: str) -> int:
    """A named grid's default seed count: its builder's ``seeds`` default."""
    default = inspect.signature(grid_builders()[name]).parameters["seeds"].default
    return int(default)


def __getattr__(name: str) -> Any:
    """``BUILTIN`` and ``DEFAULT_SEEDS``, the names this module had when it defined every
    grid itself, for code written against them: the registered grids, resolved lazily
    (the builders of a wing import this module)."""
    if name == "BUILTIN":
        return grid_builders()
    if name == "DEFAULT_SEEDS":
        return {n: default_seeds(n) for n in grid_builders()}
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def get_grid(name: str, seeds: int | None = None) -> Grid:
    """A named grid; ``seeds`` replaces its default seed count."""
    builders = grid_builders()
    if name not in builders:
        raise BenchError(f"unknown grid {name!r}; choose one of {', '.join(builders)} or pass --grid-file")
    if seeds is not None and seeds < 1:
        raise BenchError(f"--seeds must be >= 1, got {seeds}")
    from bench.design.limits import check_count

    check_count("--seeds", "seeds", seeds)
    return builders[name](seeds if seeds is not None else default_seeds(name))
