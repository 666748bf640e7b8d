"""Seed stacking: the training rollouts of S cells that differ only in their seed, as one batch.

A hierarchical rollout step costs about as much for 1 episode as for 8: most of it is a fixed
per-step cost of a few hundred small numpy and torch calls (docs/findings/, "Where the
hierarchical rollout's time goes"). The cells of one configuration (the paper grid runs 3
seeds of each) can share those calls: ``train_stacked`` runs one training iteration of every
method in ``methods`` with their episodes in one batch, seed-major (seed s's B episodes are
rows s B..(s+1) B), and leaves each method exactly where its own ``train_iteration`` would:

* scenarios: each seed's ``train_batch`` (its own generator), concatenated (``StackedBatch``);
* loss draws: ``StackedRNG`` gives every (S B, ...) draw as each seed's own (B, ...) draw;
* actions: ``StackedChoice`` samples each seed's slice with its own generator, and not at
  all once every episode of that seed has ended (its own run would have stopped; the
  generator's state stays what it would be);
* forwards: ``Method.stack_view`` stacks the seeds' weights so that one batched matmul
  computes each seed's slice with the shapes of its own run (the hierarchical method,
  group_layers), or runs each seed's own network on its slice (the decentralized baseline
  and IC3Net, whose rollouts share the environment, observations and channel but not their
  networks; IC3Net's LSTM state of each seed is its own rows);
* updates: each method updates from its own slice of the rollout buffer (contiguous copies,
  its own step count) and of whatever else the view's ``stack_state`` splits, with its own
  optimizer.

So a stacked cell gives the same numbers, bit for bit, as the same cell trained alone
(tests/algorithms/hierarchical/test_seed_stack.py), whichever cells it is stacked with.
"""
from __future__ import annotations

import copy
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from algorithms.common.episodes import EpisodeBatch
from algorithms.common.execution import TRAIN, ExecutionMode, sample_categorical
from algorithms.common.trainer import RolloutBuffer
from envs.tasks import TaskStream


class StackedRNG:
    """The generators of S batches as one: ``random((S B, ...))`` is the concatenation of
    each part's ``random((B, ...))``, drawn in seed order (what each part's own run draws)."""

    def __init__(self, rngs: Sequence[np.random.Generator], sizes: Sequence[int]) -> None:
        self.rngs, self.sizes = list(rngs), [int(b) for b in sizes]

    def random(self, shape: tuple[int, ...]) -> np.ndarray:
        shape = tuple(shape)
        if not shape or shape[0] != sum(self.sizes):
            raise ValueError(f"StackedRNG: draws must lead with the {sum(self.sizes)} stacked "
                             f"episodes, got shape {shape}")
        return np.concatenate([r.random((b, *shape[1:])) for r, b in zip(self.rngs, self.sizes, strict=True)])

    def spawn(self, n: int) -> list[StackedRNG]:
        """``n`` children, each the stack of every part's child (what each part's run spawns)."""
        kids = [r.spawn(n) for r in self.rngs]
        return [StackedRNG([k[i] for k in kids], self.sizes) for i in range(n)]


class StackedBatch(EpisodeBatch):
    """The episodes of S batches on one core, seed-major; ``rng`` is a ``StackedRNG``."""

    def __init__(self, parts: Sequence[EpisodeBatch]) -> None:
        first = parts[0]
        self.config, self.parts = first.config, list(parts)
        self.sizes = [p.core.batch for p in parts]
        # ignore: StackedRNG stands in for the batch's Generator (the draws EpisodeBatch makes,
        # each part's from its own stream); it is no Generator subclass
        self.rng = StackedRNG([p.rng for p in parts], self.sizes)  # type: ignore[assignment]
        self.starts = np.concatenate([p.starts for p in parts])
        self.goals = np.concatenate([p.goals for p in parts])
        self.core = type(first.core)(first.config, first.core.layout)
        tasks = None if first.core.tasks is None else TaskStream.stack(  # lifelong: each part's stream
            first.core.layout, first.core.n, [p.core.tasks for p in parts if p.core.tasks is not None])
        self.core.reset(self.starts, self.goals, tasks)

    def bounds(self) -> list[tuple[int, int]]:
        """(first, end) episode rows of every part."""
        ends = np.cumsum(self.sizes)
        return [(int(e - b), int(e)) for b, e in zip(self.sizes, ends, strict=True)]


def new_view(cls: Any, methods: Sequence[Any]) -> Any:
    """A fresh ``cls`` for ``methods`` (cells that differ only in their seed) to become their
    stack view; building it does not move torch's global stream. ValueError when they differ
    in more."""
    first = methods[0]
    if any(type(m) is not cls or m.env != first.env or m.params != first.params for m in methods):
        raise ValueError("stack_view: the methods must differ only in their seed")
    rng = torch.get_rng_state()
    view = cls(first.env, first.params.model_dump(), seed=first.seed, device=first.device)
    torch.set_rng_state(rng)
    return view


class OwnNetworksStack:
    """Seed stacking of a method whose stacked rollout shares the environment, observations
    and channel while each seed's own network (the attribute ``STACK_NET``) computes its own
    B episodes, with the shapes of its own run (the decentralized baseline, IC3Net): a mixin
    listed before ``Method``. ``load_stack`` keeps (network, first, end episode) per seed in
    ``_seeds``, which the method's rollout forward reads; None outside a stack view."""

    STACK_AXIS = 0  # the episodes' axis of the logits (B, N, K)
    STACK_NET = ""  # the attribute holding a seed's network
    _seeds: list[tuple[Any, int, int]] | None = None

    @classmethod
    def stackable(cls, params: Any) -> bool:
        return True

    @classmethod
    def stack_view(cls, methods: Sequence[Any]) -> Any:
        """The rollout of S seeds of one configuration as one batch (``train_stacked``)."""
        return new_view(cls, methods)

    def load_stack(self, methods: Sequence[Any]) -> None:
        b = methods[0].params.batch_episodes
        self._seeds = [(getattr(m, self.STACK_NET), k * b, (k + 1) * b) for k, m in enumerate(methods)]


@dataclass(frozen=True)
class StackedChoice:
    """Training samples (T = 1) of a stacked rollout: logits (X, S B, ..., K) (``axis`` 1, the
    hierarchical method's) or (S B, ..., K) (``axis`` 0) are split along the episodes and each
    seed's slice is sampled with that seed's generator, while any of its episodes runs."""

    gens: Sequence[torch.Generator]
    batch: StackedBatch
    mode: ExecutionMode = ExecutionMode(TRAIN, 1.0)
    gen: None = None
    training: bool = True
    axis: int = 1

    @property
    def name(self) -> str:
        return self.mode.name

    def __call__(self, logits: torch.Tensor) -> torch.Tensor:
        ended = self.batch.core.ended
        out = []
        for gen, (lo, hi) in zip(self.gens, self.batch.bounds(), strict=True):
            part = logits.narrow(self.axis, lo, hi - lo).contiguous()
            if ended[lo:hi].all():  # this seed's run has stopped: no draw
                out.append(torch.zeros(part.shape[:-1], dtype=torch.int64))
            else:
                out.append(sample_categorical(part, 1.0, gen))
        return torch.cat(out, dim=self.axis)


def split_buffer(buf: RolloutBuffer, lo: int, hi: int) -> RolloutBuffer:
    """Episodes lo..hi of a stacked rollout buffer as the buffer of their own run: contiguous
    copies, and the steps that run lasted (until its last episode ended)."""
    part = copy.copy(buf)
    part.data = {k: np.ascontiguousarray(v[:, lo:hi]) for k, v in buf.data.items()}
    part.rewards = np.ascontiguousarray(buf.rewards[:, lo:hi])
    part.running = np.ascontiguousarray(buf.running[:, lo:hi])
    steps = np.flatnonzero(part.running[: buf.t].any(axis=1))
    part.t = int(steps[-1]) + 1 if steps.size else 0
    return part


def train_stacked(methods: Sequence[Any], view: Any | None = None) -> list[list[dict[str, Any]]]:
    """One training iteration of every method, their rollouts as one batch; returns each
    method's rows (as its own ``train_iteration`` would). ``view``: a ``stack_view`` of these
    methods to reuse (its parameters are refreshed here)."""
    if len(methods) == 1:
        return [methods[0].train_iteration()]
    t0 = time.perf_counter()
    view = view if view is not None else type(methods[0]).stack_view(methods)
    view.load_stack(methods)
    batch = StackedBatch([m.train_batch() for m in methods])
    with torch.inference_mode():
        choice = StackedChoice([m.torch_gen for m in methods], batch, axis=getattr(view, "STACK_AXIS", 1))
        state, rows = view.run(batch, choice)
    shared = (time.perf_counter() - t0) / len(methods)  # the rollout, shared by the seeds
    out = []
    for m, (lo, hi) in zip(methods, batch.bounds(), strict=True):
        t1 = time.perf_counter()
        own = copy.copy(state)
        own.buffer = split_buffer(state.buffer, lo, hi)
        if hasattr(view, "stack_state"):  # more of the state per episode (IC3Net's kept LSTM states)
            own = view.stack_state(own, lo, hi)
        losses = m.update(own)
        out.append(m.finish_iteration(rows[lo:hi], losses, shared + time.perf_counter() - t1))
    return out
