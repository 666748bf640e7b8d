"""Cost estimates of cells and grids, from throughput constants kept in one place.

cost (core-seconds) = (training episodes + evaluation episodes * execution modes)
                      * horizon * N / agent-steps per second on one core

(a learned cell is evaluated in every execution mode: argmax, sample and sample@T per
temperature; a planner in one.)

This is an upper bound on the simulated agent-steps (episodes end early when every robot
has arrived) and ignores Ray start-up and checkpoint writes. The constants below come from
``bench perf``; re-measure on your machine with ``bench perf --suite all``.
"""
from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bench.cells import Cell

# Agent-steps (robots x environment steps) per second on one core at the measured N,
# for training (rollout plus update, amortized) and evaluation; other N interpolate
# piecewise linearly (clamped). Evaluation: MEASURED with `bench perf --suite
# {hierarchical,baselines,pibt}` on 2026-11-22 (quiet 2-core x86_64 box, one torch thread,
# batch 8, untrained policies, N = 100 on the MovingAI map for hierarchical and PIBT,
# wh100 for the baselines), rounded. Training: those 2026-11-22 rates times the speed-up of
# the current code over commit 81f9c6a measured in one run on 2026-11-30 with
# `scripts/perf_compare.py --sizes 20 40 100 --rounds 2 --iterations 2` (MovingAI map,
# batch 8, horizon 200, process CPU time, medians; the box was shared, load average
# 12-19, so its absolute rates are low and only the ratios are used): hierarchical 1.37x
# (N=20) / 1.24x (N=100), decentralized 0.99x / 1.41x, IC3Net 1.34x / 1.15x; hierarchical
# training then times the 1.11x (N=40, used for N=20) / 1.34x (N=100) of commit 8bdc317 over
# 60770c5 measured the same way on 2026-12-02 (quiet box, 2 rounds). Re-measure on
# your machine with `bench perf --suite train` (env-steps/s per cell, wall and CPU).
AGENT_STEPS_PER_S: dict[str, dict[str, dict[int, float]]] = {
    "hierarchical": {"train": {20: 42_000.0, 100: 102_000.0}, "eval": {20: 49_000.0, 100: 116_000.0}},
    "decentralized": {"train": {20: 108_000.0, 100: 113_000.0}, "eval": {20: 160_000.0, 100: 163_000.0}},
    "ic3net": {"train": {20: 82_000.0, 100: 115_000.0}, "eval": {20: 180_000.0, 100: 254_000.0}},
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
    """(training, evaluation) agent-steps of a cell at most: episodes * horizon * N, the
    evaluation episodes counted once per execution mode."""
    per_episode = float(cell.horizon * cell.n_robots)
    return cell.episodes * per_episode, cell.eval_episodes * len(cell.execution_modes()) * per_episode


def cell_seconds(cell: Cell) -> float:
    """Estimated core-seconds of one cell (upper bound; see the module docstring)."""
    train, ev = cell_agent_steps(cell)
    return train / rate(cell.method, "train", cell.n_robots) + ev / rate(cell.method, "eval", cell.n_robots)


def grid_cell_hours(cells: Iterable[Cell]) -> float:
    """Estimated cell-hours (core-hours) of a whole grid."""
    return sum(cell_seconds(c) for c in cells) / 3600.0
