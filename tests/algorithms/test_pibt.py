"""PIBT planner reference (algorithms/pibt.py). Runtime about 10 s on a loaded 2-core box."""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

from algorithms.common.episodes import EpisodeBatch, batch_rng
from algorithms.common.execution import ActionChoice
from algorithms.pibt import FREE, PIBTMethod, initial_priority, plan_episode
from envs import EnvConfig
from envs.actions import WAIT
from envs.layouts import MAPS_DIR, from_ascii

REAL_MAP = MAPS_DIR / "warehouse-10-20-10-2-1.map"  # bundled copy of the MovingAI map


def _run_checked(method: PIBTMethod, batch: EpisodeBatch) -> EpisodeBatch:
    """Run the shared loop by hand and check every StepResult: the planned joint move is
    executed exactly (no collision, no invalid move, no robot held back by the core)."""
    core = batch.core
    state = method.begin(batch, ActionChoice.evaluate("planner"))
    nxt = method.layout.next_cell
    while batch.running:
        dec = method.decide(batch, state, True)
        planned = np.where(core.done | core.ended[:, None], core.pos, nxt[core.pos, dec.actions])
        res = core.step(dec.actions)
        assert not res.collision.any(), f"collision at t={core.t}"
        assert not res.invalid.any(), f"invalid move at t={core.t}"
        assert (core.pos == planned).all(), "a planned move was reverted by the core"
        method.observe(batch, state, res)
    return batch


# ------------------------------------------------------------ the real map
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_pibt__real_map_100_robots_all_reach_goals_without_collisions(seed):
    cfg = EnvConfig(n_robots=100, layout=str(REAL_MAP), horizon=500)
    m = PIBTMethod(cfg, {"eval_chunk": 2}, seed=seed)
    batch = _run_checked(m, EpisodeBatch(cfg, 2, batch_rng(seed, 1, 0), m.layout))
    assert batch.core.done.all()
    assert batch.core.t < 500
    rows = m.evaluate(0)  # the shared loop and its metrics agree
    assert all(r["success_rate"] == 1.0 and r["collision_rate"] == 0.0
               and r["invalid_rate"] == 0.0 and r["steps"] < 500 for r in rows)


def test_pibt__stay_mode_finished_robots_are_fixed_obstacles_and_nothing_collides():
    cfg = EnvConfig(n_robots=100, layout=str(REAL_MAP), horizon=120, on_goal="stay")
    m = PIBTMethod(cfg, seed=3)
    batch = EpisodeBatch(cfg, 2, batch_rng(3, 1, 0), m.layout)
    core, state = batch.core, m.begin(batch, True)
    while batch.running:
        done_pos = np.where(core.done, core.pos, -1)
        dec = m.decide(batch, state, True)
        assert (dec.actions[core.done] == WAIT).all()
        res = core.step(dec.actions)
        assert not res.collision.any() and not res.invalid.any()
        assert (np.where(done_pos >= 0, core.pos, -1) == done_pos).all()
        m.observe(batch, state, res)
    assert core.done.mean() > 0.5


# ------------------------------------------------------------ small layouts
RING = """
.......
.@@@@@.
.......
"""


def _episode(tmp_path: Path, layout_text: str, starts, goals, seed: int = 0):
    """A method and a one-episode batch on an ASCII layout with an explicit scenario."""
    path = tmp_path / "small.txt"
    path.write_text(layout_text)
    cfg = EnvConfig(n_robots=len(starts), layout=str(path), horizon=60, groups=1)
    m = PIBTMethod(cfg, seed=seed)
    batch = EpisodeBatch(cfg, 1, batch_rng(seed, 1, 0), m.layout)
    batch.core.reset(m.layout.to_index(np.array(starts))[None], m.layout.to_index(np.array(goals))[None])
    return m, batch


@pytest.mark.parametrize("seed", range(6))
def test_pibt__head_on_in_a_ring_corridor_needs_inheritance_and_succeeds(tmp_path, seed):
    # A and B face each other in a 1-wide ring; whoever has priority pushes the other
    # (priority inheritance) along the ring until it can pass round the loop.
    m, batch = _episode(tmp_path, RING, [(0, 2), (0, 3)], [(0, 5), (0, 0)], seed=seed)
    _run_checked(m, batch)
    assert batch.core.done.all()


def test_pibt__corridor_follower_moves_in_the_same_step(tmp_path):
    # Chain 0 -> 1 -> 2 in a corridor, all heading right; agent 0 has top priority. With
    # inheritance the whole train moves at once (follow moves), none waits.
    m, batch = _episode(tmp_path, RING, [(0, 0), (0, 1), (0, 2)], [(0, 6), (0, 5), (0, 4)])
    state = m.begin(batch, True)
    state.priority[:] = [[3.5, 2.5, 1.5]]
    dec = m.decide(batch, state, True)
    assert dec.actions.tolist() == [[3, 3, 3]]  # all Right
    res = batch.core.step(dec.actions)
    assert not res.collision.any()


def test_plan_episode__inheritance_chain_moves_the_occupants_out_of_the_way():
    # Path graph 0-1-2-3. Agent 0 at cell 1 wants cell 2 (held by agent 1, low priority),
    # agent 1 prefers cell 1 (swap: forbidden), cannot stay (claimed), so takes 3.
    cand = [[2, 1, 0], [1, 2, 3]]
    to = [FREE, FREE]
    nxt, now = [FREE] * 4, [FREE, 0, 1, FREE]
    plan_episode([0, 1], [1, 2], to, cand, nxt, now)
    assert to == [2, 3]
    assert nxt == [FREE, FREE, 0, 1]


def test_plan_episode__backtracks_when_the_occupant_is_stuck():
    # Star: cell 0 (a dead end off cell 1), cells 2 and 3 also off cell 1.
    # Agent 0 at 1 prefers 0 (held by agent 1, whose only neighbour is 1 -> it fails);
    # agent 0 backtracks to its next candidate 2.
    cand = [[0, 2, 1], [1, 0]]
    to = [FREE, FREE]
    nxt, now = [FREE] * 4, [1, 0, FREE, FREE]
    plan_episode([0, 1], [1, 0], to, cand, nxt, now)
    assert to == [2, 0]
    assert nxt[2] == 0 and nxt[0] == 1


def _reference_pibt(order, frm, to, cand, nxt, now):
    """Recursive funcPIBT as in the published pseudo-code (slow reference)."""

    def func(i: int) -> bool:
        for v in cand[i]:
            if nxt[v] != FREE:
                continue
            j = now[v]
            if j != FREE and to[j] == frm[i]:
                continue
            to[i] = v
            nxt[v] = i
            if j != FREE and to[j] == FREE and not func(j):
                continue
            return True
        to[i] = frm[i]
        nxt[frm[i]] = i
        return False

    for i in order:
        if to[i] == FREE:
            func(i)


def test_plan_episode__matches_the_recursive_reference_on_random_crowds():
    rng = np.random.default_rng(0)
    lay = from_ascii("\n".join(["." * 7] * 6))
    f = lay.n_free
    for _ in range(200):
        n = int(rng.integers(2, 30))
        frm = rng.choice(f, n, replace=False).tolist()
        nb = lay.next_cell[frm]  # (n, 5)
        cand = [list(rng.permutation(row)) for row in nb]
        cand = [[int(c) for c in row] for row in cand]
        order = rng.permutation(n).tolist()
        fixed = rng.random(n) < 0.2
        outs = []
        for impl in (plan_episode, _reference_pibt):
            to = [frm[i] if fixed[i] else FREE for i in range(n)]
            nxt, now = [FREE] * f, [FREE] * f
            for i in range(n):
                now[frm[i]] = i
                if fixed[i]:
                    nxt[frm[i]] = i
            impl(order, frm, to, cand, nxt, now)
            outs.append(to)
        assert outs[0] == outs[1]
        # The plan itself has no vertex or swap conflict.
        to = outs[0]
        assert len(set(to)) == n
        pos_of = {c: i for i, c in enumerate(frm)}
        for i in range(n):
            j = pos_of.get(to[i])
            assert j is None or j == i or to[j] != frm[i]


def test_initial_priority__farther_first_then_random():
    d = np.array([[3, 1, 3, 0]])
    eps = initial_priority(d, np.random.default_rng(0))
    assert ((eps >= 0) & (eps < 1)).all()
    assert eps[0, 0] > eps[0, 1] and eps[0, 2] > eps[0, 1] and eps[0, 1] > eps[0, 3]


# ------------------------------------------------------------ contract
def _same_rows(a: list[dict], b: list[dict]) -> bool:
    return pd.DataFrame(a).equals(pd.DataFrame(b))  # NaN-aware, string columns included


def test_pibt__same_seed_same_metrics_and_other_seed_differs():
    cfg = EnvConfig(n_robots=40, layout="wh40", horizon=200)
    a = PIBTMethod(cfg, {"eval_chunk": 2}, seed=5).evaluate(0)
    b = PIBTMethod(cfg, {"eval_chunk": 2}, seed=5).evaluate(0)
    c = PIBTMethod(cfg, {"eval_chunk": 2}, seed=6).evaluate(0)
    assert _same_rows(a, b)
    assert [r["team_return"] for r in a] != [r["team_return"] for r in c]


def test_pibt__learns_nothing_and_state_dict_round_trips():
    cfg = EnvConfig(n_robots=20, layout="wh20", horizon=100)
    m = PIBTMethod(cfg, {"eval_chunk": 2}, seed=1)
    assert not m.learned and m.train_iteration() == []
    buf = io.BytesIO()
    torch.save(m.state_dict(), buf)
    buf.seek(0)
    m2 = PIBTMethod(cfg, {"eval_chunk": 2}, seed=1)
    m2.load_state_dict(torch.load(buf, weights_only=True))
    assert _same_rows(m.evaluate(3), m2.evaluate(3))
