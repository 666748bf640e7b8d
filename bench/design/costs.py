"""Cost estimates of cells and grids, from throughput constants kept in one place.

cost (worker-seconds) = training episodes * horizon * N / training rate
                        / seed-stacking gain (``--stack-seeds``)
                      + evaluation episodes * execution modes * horizon * N / evaluation rate

(a learned cell is evaluated in every execution mode: argmax, sample and sample@T per
temperature; a planner in one.) The agent-steps are an upper bound (episodes end early
when every robot has arrived); the rates are *effective*: observed on finished cells
against that same upper bound (bench/design/cost_calibration.py), so they include early ends,
checkpoint writes and the load of the machine the cells ran on.
"""
from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bench.design.cells import Cell

Rates = dict[str, dict[str, dict[int, float]]]

# Effective agent-steps (robots x environment steps, the upper bound above) per second
# of one worker at the observed N, for training and evaluation; other N interpolate
# piecewise linearly (clamped). OBSERVED on the committed reproduction's done cells
# (reproduction/full: the paper's budgets, 1-2 workers on the 2-core x86_64
# VM, wall time, on the commits its manifest lists; the cells it trained itself, seed-stacked
# by 3 and scaled back to one seed by stack_gain, and the cells it copied from
# reproduction/paper where it trained none at that method and N): the median per (method, N)
# of bench/design/cost_calibration.py's rates, 2 significant digits, in cost_rates.json,
# which `python scripts/calibrate_costs.py reproduction/full --stack-seeds 3 --exclude-run
# reproduction/paper --write` rebuilds (a test keeps the two equal). Their spread is this
# box's (0.5-2x between cells of one configuration run at different times), so an
# estimate is good to about a factor of 2; `bench grids --rates-from RUN` estimates with
# your own run's. Methods the reproduction has not finished a cell of fall back to
# FALLBACK_RATES: PIBT (no training) at its `bench perf --suite pibt` rate.
# Earlier the training rates were evaluation rates times measured speed-ups,
# which undercounted a paper cell 2-4x (docs/decisions/0096).
RATES_FILE = Path(__file__).with_name("cost_rates.json")
FALLBACK_RATES: Rates = {
    "pibt": {"train": {20: float("inf"), 100: float("inf")}, "eval": {20: 330_000.0, 100: 330_000.0}},
}
DEFAULT_RATE = {"train": {20: 20_000.0, 100: 20_000.0}, "eval": {20: 40_000.0, 100: 40_000.0}}


def merge_rates(base: Rates, observed: Rates) -> Rates:
    """``base`` with each (method, phase) that ``observed`` has replaced by the observed
    points; a method with one phase observed gets the other from ``base`` or
    ``DEFAULT_RATE``. Neither input is modified."""
    out = {m: {ph: dict(pts) for ph, pts in phases.items()} for m, phases in base.items()}
    for method, phases in observed.items():
        for phase, pts in phases.items():
            out.setdefault(method, {})[phase] = dict(pts)
    for phases in out.values():
        for phase in ("train", "eval"):
            phases.setdefault(phase, dict(DEFAULT_RATE[phase]))
    return out


def rates_of(content: dict) -> Rates:
    """The ``rates`` of a cost_rates.json's content, N keys as ints."""
    return {m: {ph: {int(n): float(r) for n, r in pts.items()} for ph, pts in phases.items()}
            for m, phases in content["rates"].items()}


def read_rates_file(path: Path = RATES_FILE) -> Rates:
    """The ``rates`` of a cost_rates.json, N keys as ints."""
    return rates_of(json.loads(path.read_text()))


_BUILTIN = json.loads(RATES_FILE.read_text())
AGENT_STEPS_PER_S: Rates = merge_rates(FALLBACK_RATES, rates_of(_BUILTIN))
RATES_RUN: str = _BUILTIN["run"]  # the run they were observed on
MEASURED = True
LABEL = "measured" if MEASURED else "estimate"

# Seed stacking (`bench run --stack-seeds`): per-cell training speed-up of 3 seeds in one
# worker over one, MEASURED for the hierarchical method with `bench perf --suite train`
# (8 episodes x 200 steps per update, MovingAI map, CPU time, medians of 3 rounds):
# 1.47x at N = 40, 1.22x at N = 100. The decentralized baseline and IC3Net stack too, bit
# for bit, but gained nothing measurable (2026-12-07: 1.08x / 0.97x and 1.04x / 0.94x at
# N = 40 / 100; docs/findings), so they have no entry (gain 1) and `auto` leaves them alone.
# Other stack sizes follow the model the measurement fits: a share x of a cell's training
# is the rollout's fixed per-step cost, which S seeds share, so gain(S) = 1 / (1 - x (1 - 1/S))
# and x = 1.5 (1 - 1/gain(3)).
STACK_GAIN_3: dict[str, dict[int, float]] = {"hierarchical": {40: 1.47, 100: 1.22}}


def _interpolate(points: dict[int, float], n_robots: int) -> float:
    """Piecewise linear in N between the given points, clamped outside them."""
    pts = sorted(points.items())
    if n_robots <= pts[0][0]:
        return pts[0][1]
    for (n0, r0), (n1, r1) in zip(pts[:-1], pts[1:], strict=True):
        if n_robots <= n1:
            return r0 if r0 == r1 else r0 + (n_robots - n0) / (n1 - n0) * (r1 - r0)
    return pts[-1][1]


def rate(method: str, phase: str, n_robots: int, rates: Rates | None = None) -> float:
    """Agent-steps per second of ``method`` in ``phase`` ("train"/"eval") at ``n_robots``
    (``rates``: default the built-in ``AGENT_STEPS_PER_S``)."""
    table = AGENT_STEPS_PER_S if rates is None else rates
    return _interpolate(table.get(method, DEFAULT_RATE)[phase], n_robots)


def stack_gain(method: str, n_robots: int, seeds: int) -> float:
    """Training speed-up per cell of ``seeds`` cells trained seed-stacked (1 for one
    seed, or a method that does not stack); see ``STACK_GAIN_3``."""
    if seeds < 2 or method not in STACK_GAIN_3:
        return 1.0
    fixed = 1.5 * (1.0 - 1.0 / _interpolate(STACK_GAIN_3[method], n_robots))
    return 1.0 / (1.0 - fixed * (1.0 - 1.0 / seeds))


def cell_agent_steps(cell: Cell) -> tuple[float, float]:
    """(training, evaluation) agent-steps of a cell at most: episodes * horizon * N, the
    evaluation episodes counted once per execution mode."""
    per_episode = float(cell.horizon * cell.n_robots)
    return cell.episodes * per_episode, cell.eval_episodes * len(cell.execution_modes()) * per_episode


def cell_seconds(cell: Cell, rates: Rates | None = None, stacked: int = 1) -> float:
    """Estimated worker-seconds of one cell, trained in a stack of ``stacked`` seeds."""
    train, ev = cell_agent_steps(cell)
    train_s = train / rate(cell.method, "train", cell.n_robots, rates) if train else 0.0
    return (train_s / stack_gain(cell.method, cell.n_robots, stacked)
            + ev / rate(cell.method, "eval", cell.n_robots, rates))


# `bench run --stack-seeds auto` (its default; docs/decisions/0237): the stack size it uses
# where stacking pays, the size whose gain is measured (STACK_GAIN_3).
AUTO = "auto"
AUTO_STACK = 3
StackSeeds = int | str  # a count, or AUTO


def parse_stack_seeds(text: str | int) -> StackSeeds:
    """``--stack-seeds``: ``auto`` or a count of at least 1; ValueError naming the value else."""
    if isinstance(text, str) and text.strip().lower() == AUTO:
        return AUTO
    try:
        k = int(text)
    except ValueError:
        k = 0
    if k < 1:
        raise ValueError(f"--stack-seeds {text!r}: give auto or a count of at least 1")
    return k


def auto_stacking(seconds: Sequence[float], stackable: Sequence[bool], workers: int) -> tuple[list[int], int]:
    """What ``--stack-seeds auto`` does with cells still to train (``seconds``: their
    estimated unstacked seconds left, in grid order): (the cells that run first, each alone,
    longest first; the stack size of the others). The ``workers`` longest cells are the
    run's critical path: each gets a worker of its own, unstacked (stacking would lengthen
    it). The other cells of stackable methods train in seed stacks of up to AUTO_STACK when
    there are more of them than workers (stacking then saves CPU without idling a worker),
    else alone."""
    order = sorted(range(len(seconds)), key=lambda i: (-seconds[i], i))
    solo = order[:max(1, workers)]
    alone = set(solo)
    rest = sum(1 for i, ok in enumerate(stackable) if ok and i not in alone)
    return solo, AUTO_STACK if rest > workers else 1


def stack_pays(cell: Cell) -> bool:
    """Whether ``--stack-seeds auto`` stacks this cell's seeds: its method stacks them and
    a stack of AUTO_STACK is measured to save CPU (``STACK_GAIN_3``)."""
    return cell.stackable() and stack_gain(cell.method, cell.n_robots, AUTO_STACK) > 1.0


def stack_sizes(cells: Sequence[Cell], stack_seeds: StackSeeds, workers: int = 1,
                stackable: Callable[[Cell], bool] | None = None) -> list[int]:
    """For each cell, the size of the seed stack ``bench run --stack-seeds`` trains it in:
    the cells of one configuration (all but the seed) of a stackable method (``stackable``,
    default ``Cell.stackable``), in grid order, in stacks of up to ``stack_seeds``; 1
    otherwise. ``auto`` (with ``workers``): ``auto_stacking`` over the whole grid with the
    cells where stacking pays (``stack_pays``), its critical cells alone."""
    sizes = [1] * len(cells)
    solo: list[int] | set[int] = []
    if stack_seeds == AUTO:
        stackable = stack_pays
        solo, stack_seeds = auto_stacking([cell_seconds(c) for c in cells], [stackable(c) for c in cells], workers)
    assert isinstance(stack_seeds, int)
    solo = set(solo)
    if stack_seeds < 2:
        return sizes
    groups: dict[str, list[int]] = {}
    for i, c in enumerate(cells):
        if (c.stackable() if stackable is None else stackable(c)) and i not in solo:
            groups.setdefault(c.model_copy(update={"seed": 0}).canonical_json(), []).append(i)
    for members in groups.values():
        for lo in range(0, len(members), stack_seeds):
            chunk = members[lo: lo + stack_seeds]
            for i in chunk:
                sizes[i] = len(chunk)
    return sizes


def grid_cell_hours(cells: Iterable[Cell], rates: Rates | None = None, stack_seeds: StackSeeds = 1,
                    workers: int = 1) -> float:
    """Estimated worker-hours of a whole grid (with ``bench run --stack-seeds stack_seeds
    --workers workers``)."""
    cells = list(cells)
    sizes = stack_sizes(cells, stack_seeds, workers)
    return sum(cell_seconds(c, rates, k) for c, k in zip(cells, sizes, strict=True)) / 3600.0
