"""``greedy``: every robot takes the move that brings it closest to its goal, unless
another robot stands on that cell now; no learning, no messages (a planner)."""
from __future__ import annotations

import numpy as np

from algorithms.base import Method, MethodParams
from algorithms.common.episodes import Decision, EpisodeBatch
from algorithms.common.execution import ActionChoice
from envs.actions import WAIT


class GreedyParams(MethodParams):
    """No hyperparameters beyond the shared ones (``batch_episodes``, ``eval_chunk``)."""


class GreedyPlanner(Method):
    name = "greedy"
    display_name = "Greedy (example)"
    color = "#cc78bc"
    learned = False
    payload_model = "none: robots see only their own cell's neighbours (0 scalars sent)"
    Params = GreedyParams

    def begin(self, batch: EpisodeBatch, choice: ActionChoice) -> np.random.Generator:
        return batch.rng.spawn(1)[0]  # tie-breaks: a pure function of the batch's seed

    def decide(self, batch: EpisodeBatch, state: np.random.Generator, choice: ActionChoice) -> Decision:
        core = batch.core
        nxt = self.layout.next_cell[core.pos]  # (B, N, 5) cell each action leads to
        key = core.distances_to_goal(nxt) + 0.1 * state.random(nxt.shape)  # (B, N, 5)
        occupied = np.zeros((core.batch, self.layout.n_free), dtype=bool)  # (B, F)
        rows, robots = np.nonzero(core.occupying)
        occupied[rows, core.pos[rows, robots]] = True
        taken = occupied[np.arange(core.batch)[:, None, None], nxt]  # (B, N, 5)
        taken[..., WAIT] = False  # staying on one's own cell is always allowed
        key[taken] = np.inf
        actions = key.argmin(axis=-1).astype(np.int64)
        actions[core.done | core.ended[:, None]] = WAIT
        return Decision(actions=actions, payload=0.0)
