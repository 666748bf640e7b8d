"""Cost estimates of cells and grids, from throughput constants kept in one place.

cost (core-seconds) = (training episodes + evaluation episodes) * horizon * N
                      / agent-steps per second on one core

This is an upper bound on the simulated agent-steps (episodes end early when every robot
has arrived) and ignores Ray start-up and checkpoint writes. The constants below come from
``bench perf``; re-measure on your machine with ``bench perf --suite all``.
"""
from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bench.cells import Cell

# Agent-steps (robots x environment steps) per second on one core at N = 20 and N = 100,
# for training (rollout plus update, amortized) and evaluation; other N interpolate
# linearly (clamped). MEASURED with `bench perf --suite {hierarchical,baselines,pibt}` on
# 2026-11-22 (2-core x86_64 box, one torch thread, batch 8, untrained policies, N = 100 on
# the MovingAI warehouse map for hierarchical and PIBT, wh100 for the baselines), rounded.
AGENT_STEPS_PER_S: dict[str, dict[str, dict[int, float]]] = {
    "hierarchical": {"train": {20: 28_000.0, 100: 61_000.0}, "eval": {20: 49_000.0, 100: 116_000.0}},
    "decentralized": {"train": {20: 109_000.0, 100: 80_000.0}, "eval": {20: 160_000.0, 100: 163_000.0}},
    "ic3net": {"train": {20: 61_000.0, 100: 100_000.0}, "eval": {20: 180_000.0, 100: 254_000.0}},
    "pibt": {"train": {20: float("inf"), 100: float("inf")}, "eval": {20: 330_000.0, 100: 330_000.0}},
}
DEFAULT_RATE = {"train": {20: 20_000.0, 100: 20_000.0}, "eval": {20: 40_000.0, 100: 40_000.0}}
MEASURED = True
LABEL = "measured" if MEASURED else "estimate"


def rate(method: str, phase: str, n_robots: int) -> float:
    """Agent-steps per second of ``method`` in ``phase`` ("train"/"eval") at ``n_robots``:
    piecewise linear between the measured N, clamped outside them."""
    points = sorted(AGENT_STEPS_PER_S.get(method, DEFAULT_RATE)[phase].items())
    if n_robots <= points[0][0]:
        return points[0][1]
    for (n0, r0), (n1, r1) in zip(points[:-1], points[1:], strict=True):
        if n_robots <= n1:
            return r0 if r0 == r1 else r0 + (n_robots - n0) / (n1 - n0) * (r1 - r0)
    return points[-1][1]


def cell_agent_steps(cell: Cell) -> tuple[float, float]:
    """(training, evaluation) agent-steps of a cell at most: episodes * horizon * N."""
    per_episode = float(cell.horizon * cell.n_robots)
    return cell.episodes * per_episode, cell.eval_episodes * per_episode


def cell_seconds(cell: Cell) -> float:
    """Estimated core-seconds of one cell (upper bound; see the module docstring)."""
    train, ev = cell_agent_steps(cell)
    return train / rate(cell.method, "train", cell.n_robots) + ev / rate(cell.method, "eval", cell.n_robots)


def grid_cell_hours(cells: Iterable[Cell]) -> float:
    """Estimated cell-hours (core-hours) of a whole grid."""
    return sum(cell_seconds(c) for c in cells) / 3600.0
