"""PIBT: priority inheritance with backtracking, the classical planner reference.

Okumura, Machida, Défago, Tamura (AIJ 2022; facts in ../shared/REFERENCES.md). Beyond the
paper (SPEC 3): a centralized planner with full information and no learning, which tells
how far the learned methods are from a planner on the same scenarios and shows that a
layout and scenario are solvable.

Each step, for every running episode, agents are processed in decreasing priority. An
agent not yet assigned tries its current cell and its neighbours, sorted by BFS distance
D(., g_i) to its goal (random tie-break), skipping cells already claimed for the next step
and moves that would swap with the occupant. Claiming a cell whose occupant has not been
planned yet makes that occupant plan next with inherited priority; if it cannot move, the
claimer backtracks to its next candidate; with none left it stays. Only vertex and swap
conflicts are forbidden, exactly the collision rule of ``WarehouseCore.step`` (follow moves
and rotations are allowed), so the joint move it plans executes with zero collisions.

Priorities: eps_i in [0, 1) orders ties by initial distance (farther first), then randomly;
each step an agent is away from its goal its priority grows by one, on arrival it drops to
its fractional part (it is then removed or fixed, per ``on_goal``).

Vectorized outside the per-agent loop: candidate ordering (B, N, 5), priority order and
action decoding are numpy; the sequential PIBT core runs on plain Python lists with an
explicit stack (no recursion limit for any N).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from algorithms.base import BASELINE, Method, MethodParams
from algorithms.common.episodes import Decision, EpisodeBatch
from algorithms.common.execution import ActionChoice
from envs.actions import WAIT
from envs.config import EnvConfig
from envs.core import StepResult

FREE = -1  # marker in the occupancy lists and the plan


class PIBTParams(MethodParams):
    """PIBT has no hyperparameters beyond the shared ones (evaluation chunk size)."""


@dataclass
class PIBTState:
    """Controller state of one batch of B episodes."""

    rng: np.random.Generator  # tie-breaks, drawn from the batch's own generator
    priority: np.ndarray  # (B, N) float64: steps away from the goal + eps_i


def initial_priority(dist0: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(B, N) eps_i in [0, 1): larger initial distance first, then a random order.

    ``dist0`` (B, N) holds D(p_0, g_i). eps = (D + u) / (max D + 1) with u ~ U[0, 1), so
    agents with equal initial distance are ordered by u.
    """
    d = dist0.astype(np.float64)
    u = rng.random(d.shape)
    return (d + u) / (d.max(initial=0.0) + 1.0)


def plan_episode(
    order: list[int],
    frm: list[int],
    to: list[int],
    cand: list[list[int]],
    nxt_occ: list[int],
    now_occ: list[int],
) -> None:
    """One PIBT step of one episode, in place on plain lists.

    order: agents by decreasing priority. frm[i]: current cell. to[i]: planned cell,
    ``FREE`` for agents still to plan (pre-filled for agents that do not plan). cand[i]:
    candidate cells in preference order (duplicates allowed). nxt_occ[c] / now_occ[c]:
    agent claiming / standing on cell c, ``FREE`` otherwise (indexed by free-cell index).
    On return every agent has a cell in ``to`` and ``nxt_occ`` holds the claims.

    Iterative version of PIBT's recursive funcPIBT: a frame is an agent on ``stack`` and
    its candidate pointer ``ptr``; ``ok`` carries the result of the frame just popped
    (None: the top frame is fresh or resumes after a failed child).
    """
    ptr = [0] * len(frm)
    for root in order:
        if to[root] != FREE:
            continue
        stack = [root]
        ok: bool | None = None
        while stack:
            i = stack[-1]
            if ok:  # the child we inherited to found a cell: i keeps its claim
                stack.pop()
                continue
            ok = None
            cs = cand[i]
            k = ptr[i]
            src = frm[i]
            pushed = False
            while k < len(cs):
                v = cs[k]
                k += 1
                if nxt_occ[v] != FREE:  # vertex conflict
                    continue
                j = now_occ[v]
                if j != FREE and to[j] == src:  # swap (edge) conflict
                    continue
                to[i] = v
                nxt_occ[v] = i
                if j != FREE and to[j] == FREE:  # priority inheritance
                    ptr[i] = k
                    stack.append(j)
                    pushed = True
                else:
                    ok = True
                break
            if pushed:
                continue
            stack.pop()
            if ok is None:  # no candidate left: stay, and the parent backtracks
                to[i] = src
                nxt_occ[src] = i
                ok = False


class PIBTMethod(Method):
    """Centralized PIBT planner (no learning; ``train_iteration`` returns no rows)."""

    name = "pibt"
    display_name = "PIBT"
    color = "#949494"
    legend_rank = 3
    paper_role = BASELINE  # compared with the paper's method (Sec. IV)
    line_style = ":"
    payload_model = "not modelled: a centralized planner with full information (NaN in the eval rows)"
    payload_not_modelled = True
    learned = False
    Params = PIBTParams

    def __init__(self, env: EnvConfig, params: Mapping[str, Any] | None = None, seed: int = 0) -> None:
        super().__init__(env, params, seed)
        f = self.layout.n_free
        self._nxt_occ = [FREE] * f  # scratch occupancy lists, left all-FREE between uses
        self._now_occ = [FREE] * f

    def begin(self, batch: EpisodeBatch, choice: ActionChoice) -> PIBTState:
        rng = batch.rng.spawn(1)[0]
        return PIBTState(rng=rng, priority=initial_priority(batch.core.dist, rng))

    def candidates(self, batch: EpisodeBatch, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(B, N, 5) candidate cells in preference order, and (B, N, 5) next cells by action.

        Current cell and neighbours sorted by D(., g_i) with a uniform random tie-break;
        moves into a shelf or off the grid (same cell as Wait) are sorted last.
        """
        core = batch.core
        nxt = self.layout.next_cell[core.pos]  # (B, N, 5)
        key = core.distances_to_goal(nxt) + rng.random(nxt.shape)
        blocked = nxt == core.pos[..., None]
        blocked[..., WAIT] = False
        key[blocked] = np.inf
        order = np.argsort(key, axis=-1, kind="stable")
        return np.take_along_axis(nxt, order, axis=-1), nxt

    def decide(self, batch: EpisodeBatch, state: PIBTState, choice: ActionChoice) -> Decision:
        core = batch.core
        cand, nxt = self.candidates(batch, state.rng)
        prio_order = np.argsort(-state.priority, axis=1, kind="stable")
        occupying = core.occupying
        planning = ~core.done & ~core.ended[:, None]  # (B, N)
        new_pos = core.pos.copy()
        nxt_occ, now_occ = self._nxt_occ, self._now_occ
        cand_l = cand.tolist()
        for b in np.flatnonzero(~core.ended).tolist():
            frm = core.pos[b].tolist()
            to = np.where(planning[b], FREE, core.pos[b]).tolist()
            occ_b = np.flatnonzero(occupying[b]).tolist()
            for i in occ_b:
                now_occ[frm[i]] = i
                if to[i] != FREE:  # a finished robot in "stay" mode: a fixed obstacle
                    nxt_occ[frm[i]] = i
            plan_episode(prio_order[b].tolist(), frm, to, cand_l[b], nxt_occ, now_occ)
            for i in occ_b:
                now_occ[frm[i]] = FREE
                nxt_occ[to[i]] = FREE
            new_pos[b] = to
        moves = nxt[..., :WAIT] == new_pos[..., None]  # (B, N, 4)
        actions = np.where(new_pos == core.pos, WAIT, moves.argmax(axis=-1))
        actions[~planning] = WAIT
        # A centralized planner with full information: no channel, payload not modelled.
        return Decision(actions=actions.astype(np.int64), payload=np.nan)

    def observe(self, batch: EpisodeBatch, state: PIBTState, result: StepResult) -> None:
        """Priority update: +1 while away from the goal, fractional part on arrival."""
        p = state.priority
        away = result.active & ~result.reached
        p[away] += 1.0
        p[result.reached] -= np.floor(p[result.reached])
