"""Which actions a learned baseline executes: argmax, or samples from a per-batch stream.

The paper executes its own method with argmax at both levels (SPEC 3). IC3Net's reference
code always samples its actions, also when evaluating, and a reactive stochastic policy
can deadlock when made deterministic; a method may therefore evaluate with sampled
actions (its ``execution="sample"`` parameter). Evaluation samples come from a torch
generator seeded from the batch's own generator, so an evaluation chunk gives the same
rows on any worker and never touches the training stream.
"""
from __future__ import annotations

import torch

from algorithms.common.episodes import EpisodeBatch


def action_stream(
    batch: EpisodeBatch, greedy: bool, sample_eval: bool, train_gen: torch.Generator
) -> tuple[bool, torch.Generator]:
    """(greedy, generator) for the episodes of ``batch``; call once in ``begin``.

    Training (``greedy`` False) samples from the method's own stream ``train_gen``;
    evaluation is argmax unless ``sample_eval``, then it samples from a generator drawn
    from ``batch.rng`` (after the method's loss processes, so those are unaffected).
    """
    if not greedy or not sample_eval:
        return greedy, train_gen
    seed = int(batch.rng.integers(2**62))
    return False, torch.Generator().manual_seed(seed)
