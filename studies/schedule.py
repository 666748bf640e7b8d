"""Which configuration a study runs next: an exhaustive grid with seed replicates, or TPE.

A 20-point space (|R_z| x L) is cheaper to enumerate than to search: TPE re-proposed
already-tried points 3 times in 12 trials (issue #16), and a single trial per point cannot
tell a good configuration from a lucky seed. ``SearchPlan`` therefore has two modes:

* ``grid`` (default when the space has at most ``GRID_MAX`` points): the driver enqueues the
  point with the fewest live trials (complete, pruned, running or waiting), ties broken by
  a permutation seeded from the study seed. Every point thus gets replicate 0 before any
  gets replicate 1, and ``size x replicates`` trials evaluate every point ``replicates``
  times. We enqueue (``study.enqueue_trial``) instead of using Optuna's ``GridSampler``:
  the grid sampler visits each point once and then samples finished points at random, so it
  cannot balance replicates, and its choice depends on which trials other drivers finished.
* ``tpe``: the sampler proposes points; a point with a complete trial but fewer than
  ``replicates`` live ones is re-run first, so every point TPE likes is replicated too.

Replicate ``r`` of every point trains with the same seed (``replicate_seed``): replicates of
different points are paired (common random numbers), so differences between points are
not differences between seeds.
"""
from __future__ import annotations

import itertools
import json
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import optuna
from optuna.trial import FrozenTrial, TrialState

from envs.errors import BenchError
from studies.space import Value, plain, space_size
from studies.storage import REPLICATE, RETRY_OF

GRID_MAX = 64  # spaces up to this many points are searched exhaustively under "auto"
LIVE = (TrialState.COMPLETE, TrialState.PRUNED, TrialState.RUNNING, TrialState.WAITING)
SearchMode = Literal["auto", "grid", "tpe"]


def replicate_seed(study_seed: int, replicate: int) -> int:
    """Training seed of replicate ``replicate`` of any point: SeedSequence([study seed, 1, r])
    -> 31-bit int (the same for every point of the study: paired comparisons)."""
    state = np.random.SeedSequence([int(study_seed), 1, int(replicate)]).generate_state(1)
    return int(state[0] & 0x7FFFFFFF)


def point_key(params: Mapping[str, int]) -> str:
    """Canonical text of a configuration (sorted JSON), used to count its trials."""
    return json.dumps({k: plain(v) for k, v in sorted(params.items())}, sort_keys=True)


def grid_points(space: Mapping[str, Sequence[int]], seed: int) -> list[dict[str, int]]:
    """Every point of ``space`` once, in an order permuted by ``seed`` (deterministic)."""
    names = list(space)
    points = [dict(zip(names, combo, strict=True)) for combo in itertools.product(*space.values())]
    order = np.random.default_rng(np.random.SeedSequence([int(seed), 4])).permutation(len(points))
    return [points[i] for i in order]


def resolve_mode(mode: str, space: Mapping[str, Sequence[Value]]) -> Literal["grid", "tpe"]:
    """``auto`` -> ``grid`` for at most ``GRID_MAX`` points, else ``tpe``."""
    if mode == "auto":
        return "grid" if space_size(space) <= GRID_MAX else "tpe"
    if mode in ("grid", "tpe"):
        return "grid" if mode == "grid" else "tpe"
    raise BenchError(f"unknown search {mode!r}; choose auto, grid or tpe")


@dataclass(frozen=True)
class SearchPlan:
    """How the driver picks the next trial's parameters (see the module docstring)."""

    mode: Literal["grid", "tpe"]
    replicates: int
    points: tuple[dict[str, int], ...]  # grid order (all points; also used by tpe to count)

    @classmethod
    def make(cls, mode: str, space: Mapping[str, Sequence[int]], replicates: int, seed: int) -> SearchPlan:
        if replicates < 1:
            raise BenchError(f"--replicates must be >= 1, got {replicates}")
        return cls(resolve_mode(mode, space), int(replicates), tuple(grid_points(space, seed)))

    def default_trials(self) -> int:
        """Trials that evaluate every point ``replicates`` times (grid), else 20 (tpe)."""
        return len(self.points) * self.replicates if self.mode == "grid" else 20

    def next_point(self, trials: Sequence[FrozenTrial]) -> tuple[dict[str, int], int] | None:
        """(params, replicate index) to enqueue next, or None to let the sampler propose.

        Nothing is enqueued while a trial is WAITING (a re-queued crash runs first).
        """
        if any(t.state == TrialState.WAITING for t in trials):
            return None
        live = Counter(point_key(t.params) for t in trials if t.state in LIVE and t.params)
        if self.mode == "grid":
            point = min(self.points, key=lambda p: live[point_key(p)])  # min keeps grid order on ties
            return point, replicate_index(trials, point)
        complete = {point_key(t.params): t.params for t in trials if t.state == TrialState.COMPLETE}
        for key, params in complete.items():
            if live[key] < self.replicates:
                return dict(params), replicate_index(trials, params)
        return None


def replicate_index(trials: Sequence[FrozenTrial], params: Mapping[str, int],
                    before: int | None = None) -> int:
    """Replicate index for a new attempt at ``params``: the number of first attempts (trials
    not re-queued from a crash) with the same parameters, whatever their state, numbered
    below ``before`` (all of them when None)."""
    key = point_key(params)
    return sum(1 for t in trials if t.params and RETRY_OF not in t.user_attrs
               and (before is None or t.number < before) and point_key(t.params) == key)


def trial_replicate(study: optuna.Study, trial: optuna.trial.Trial) -> int:
    """The replicate index of a just-asked trial: its enqueued attribute, else counted among
    the first attempts before it (a re-queued trial counts from the trial it replaces)."""
    if REPLICATE in trial.user_attrs:
        return int(trial.user_attrs[REPLICATE])
    root = int(trial.user_attrs.get(RETRY_OF, trial.number))
    return replicate_index(study.get_trials(deepcopy=False), trial.params, before=root)
