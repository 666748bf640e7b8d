"""A method given only as ``module:Class`` (no package, no entry point): put this folder on
PYTHONPATH and name it ``wmb_random:RandomWalk`` in a grid file or ``bench eval --method``.

``RandomWalk``: every robot picks uniformly among the moves that do not run into a shelf
(Wait included): the floor of what any coordination should beat.
"""
from __future__ import annotations

import numpy as np

from algorithms.base import Method, MethodParams
from algorithms.common.episodes import Decision, EpisodeBatch
from algorithms.common.execution import ActionChoice
from envs.actions import WAIT


class RandomWalk(Method):
    name = "random_walk"
    display_name = "Random walk (example)"
    color = "#fbafe4"
    learned = False
    payload_model = "none (0 scalars sent)"
    Params = MethodParams

    def begin(self, batch: EpisodeBatch, choice: ActionChoice) -> np.random.Generator:
        return batch.rng.spawn(1)[0]

    def decide(self, batch: EpisodeBatch, state: np.random.Generator, choice: ActionChoice) -> Decision:
        core = batch.core
        nxt = self.layout.next_cell[core.pos]  # (B, N, 5)
        valid = nxt != core.pos[..., None]
        valid[..., WAIT] = True
        key = np.where(valid, state.random(valid.shape), -1.0)
        actions = key.argmax(axis=-1).astype(np.int64)
        actions[core.done | core.ended[:, None]] = WAIT
        return Decision(actions=actions, payload=0.0)
