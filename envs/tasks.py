"""Lifelong tasks (beyond the paper, SPEC 2 "Tasks"): a seeded stream of next goals.

With ``task = "lifelong"`` a robot that reaches its goal gets its next one at once and
keeps working until the horizon, as in POGEMA's ``on_target="restart"`` and the League of
Robot Runners. Goals alternate, warehouse style, between a *pickup* cell (a free cell next
to a shelf) and a *delivery* cell (a station: a free cell on the leftmost or rightmost
column of the floor, where the MovingAI warehouse maps and the presets have their open
ends); the first goal of an episode is the scenario's (a pickup, drawn as in one-shot
episodes), so the next is a delivery. A layout without shelves or stations draws every
next goal uniformly from its free cells. Only the largest connected region is used, so
every goal is reachable. A next goal is never the cell the robot stands on.

Each episode draws from its own generator (``TaskStream.stack`` joins the streams of
several batches, one generator per episode), so an episode's tasks do not depend on the
others of its batch, nor on how many random numbers the channel or the method drew.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import ndimage

from envs.layouts import Layout
from envs.scenarios import main_region

TASK_KINDS = ("one-shot", "lifelong")
_TASK_KEY = 0x7A5C  # spawn key of the task stream's generator under a batch's seed


def shelves(layout: Layout) -> np.ndarray:
    """(H, W) bool: obstacle cells of blocks that do not touch the grid's edge (the
    blocks that do are its walls)."""
    labels, _ = ndimage.label(layout.obstacles)
    edge = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    return (labels > 0) & ~np.isin(labels, edge)


def task_cells(layout: Layout) -> tuple[np.ndarray, np.ndarray]:
    """(pickups, stations): free-cell indices of the main region next to a shelf, and on its
    leftmost and rightmost columns; both the whole region when either is empty."""
    region = main_region(layout)
    padded = np.pad(shelves(layout), 1, constant_values=False)  # off the grid is no shelf
    near_shelf = padded[:-2, 1:-1] | padded[2:, 1:-1] | padded[1:-1, :-2] | padded[1:-1, 2:]
    rc = layout.cells[region]
    pickups = region[near_shelf[rc[:, 0], rc[:, 1]]]
    cols = rc[:, 1]
    stations = region[(cols == cols.min()) | (cols == cols.max())]
    stations = np.setdiff1d(stations, pickups)
    if not len(pickups) or not len(stations):
        return region, region
    return pickups, stations


def task_rng(rng: np.random.Generator, episode: int) -> np.random.Generator:
    """The task generator of episode ``episode`` under ``rng``'s seed (no draw from ``rng``):
    a child of its SeedSequence at a fixed spawn key."""
    seq = rng.bit_generator.seed_seq
    assert isinstance(seq, np.random.SeedSequence), "the task stream needs a seeded generator"
    return np.random.default_rng(np.random.SeedSequence(seq.entropy, spawn_key=(*seq.spawn_key, _TASK_KEY, episode)))


class TaskStream:
    """Next goals of B episodes of N robots; ``deliver[b, i]``: robot i's next goal is a
    delivery (else a pickup)."""

    def __init__(self, layout: Layout, n_robots: int, rngs: Sequence[np.random.Generator]) -> None:
        self.pickups, self.stations = task_cells(layout)
        self.rngs = list(rngs)
        self.deliver = np.ones((len(self.rngs), n_robots), dtype=bool)

    @classmethod
    def seeded(cls, layout: Layout, n_robots: int, batch: int, rng: np.random.Generator) -> TaskStream:
        """The stream of ``batch`` episodes under ``rng``'s seed (``task_rng``)."""
        return cls(layout, n_robots, [task_rng(rng, b) for b in range(batch)])

    @classmethod
    def stack(cls, layout: Layout, n_robots: int, streams: Sequence[TaskStream]) -> TaskStream:
        """One stream over the episodes of ``streams``, in order (each keeps its generators)."""
        out = cls(layout, n_robots, [r for s in streams for r in s.rngs])
        out.deliver = np.concatenate([s.deliver for s in streams])
        return out

    def next_goals(self, reached: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """New goal cells of the robots where ``reached`` (B, N) is True, in C order; ``pos``
        (B, N) their cells (a next goal differs from it)."""
        out = []
        for b in np.flatnonzero(reached.any(axis=1)).tolist():
            robots = np.flatnonzero(reached[b])
            deliver = self.deliver[b, robots]
            sizes = np.where(deliver, len(self.stations), len(self.pickups))
            k = (self.rngs[b].random(len(robots)) * sizes).astype(np.int64)
            goal = np.where(deliver, self.stations[np.minimum(k, len(self.stations) - 1)],
                            self.pickups[np.minimum(k, len(self.pickups) - 1)])
            same = goal == pos[b, robots]  # the next cell of the pool instead
            if same.any():
                k2 = (k + 1) % sizes
                goal = np.where(same, np.where(deliver, self.stations[k2 % len(self.stations)],
                                               self.pickups[k2 % len(self.pickups)]), goal)
            self.deliver[b, robots] = ~deliver
            out.append(goal)
        return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)
