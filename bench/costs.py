"""Cost estimates of cells and grids, from throughput constants kept in one place.

cost (core-seconds) = (training episodes + evaluation episodes) * horizon * N
                      / agent-steps per second on one core

This is an upper bound on the simulated agent-steps (episodes end early when every robot
has arrived) and ignores Ray start-up and checkpoint writes. The constants below are
ESTIMATES until the perf suites (``bench perf``) measure them on the reference machine;
update ``AGENT_STEPS_PER_S`` (and ``MEASURED``) from ``bench perf --suite all`` output.
"""
from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bench.cells import Cell

# Agent-steps (robots x environment steps) per second on one core, for training (rollout
# plus update, amortized) and evaluation. ESTIMATES: one rough timing per method at N=20
# and N=100 (batch 8, horizon 100, untrained policies) on a 2-core development box shared
# with other jobs, rounded down; replace with ``bench perf`` numbers from a quiet machine.
AGENT_STEPS_PER_S: dict[str, dict[str, float]] = {
    "hierarchical": {"train": 15_000.0, "eval": 15_000.0},
    "decentralized": {"train": 25_000.0, "eval": 40_000.0},
    "ic3net": {"train": 10_000.0, "eval": 30_000.0},
    "pibt": {"train": float("inf"), "eval": 100_000.0},
}
DEFAULT_RATE = {"train": 20_000.0, "eval": 40_000.0}  # methods registered later (tests, plugins)
MEASURED = False  # flip to True once the constants above come from ``bench perf``
LABEL = "measured" if MEASURED else "estimate"


def cell_agent_steps(cell: Cell) -> tuple[float, float]:
    """(training, evaluation) agent-steps of a cell at most: episodes * horizon * N."""
    per_episode = float(cell.horizon * cell.n_robots)
    return cell.episodes * per_episode, cell.eval_episodes * per_episode


def cell_seconds(cell: Cell) -> float:
    """Estimated core-seconds of one cell (upper bound; see the module docstring)."""
    rate = AGENT_STEPS_PER_S.get(cell.method, DEFAULT_RATE)
    train, ev = cell_agent_steps(cell)
    return train / rate["train"] + ev / rate["eval"]


def grid_cell_hours(cells: Iterable[Cell]) -> float:
    """Estimated cell-hours (core-hours) of a whole grid."""
    return sum(cell_seconds(c) for c in cells) / 3600.0
