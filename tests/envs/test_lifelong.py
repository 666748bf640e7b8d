"""Lifelong tasks (envs/tasks.py, task="lifelong" in the core, the PettingZoo adapter and
the methods): arrivals get a next goal at once, episodes run to the horizon."""
from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from algorithms.common.episodes import EpisodeBatch, batch_rng
from algorithms.registry import method_class
from envs.actions import N_ACTIONS
from envs.config import EnvConfig
from envs.core import WarehouseCore
from envs.distances import distance_cache
from envs.errors import BenchError
from envs.layouts import load_layout
from envs.tasks import task_cells
from envs.warehouse_v0 import parallel_env

MAP = "warehouse-10-20-10-2-1"  # the bundled copy of the MovingAI map (docs/decisions/0013)


def test_task_cells__pickups_by_shelves_stations_on_the_open_ends():
    layout = load_layout("tiny")  # walls all round, four 2x3 shelf blocks
    pickups, stations = task_cells(layout)
    rc = layout.cells
    assert set(rc[stations][:, 1]) == {1, 11}  # leftmost and rightmost free columns
    assert not set(pickups) & set(stations)
    for r, c in rc[pickups]:  # each pickup touches a shelf, never only the wall
        around = [(r + dr, c + dc) for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1))]
        assert any(layout.obstacles[a] and 0 < a[0] < 8 and 0 < a[1] < 12 for a in around)


def test_core__arrivals_get_the_next_goal_and_the_episode_runs_to_the_horizon():
    env = EnvConfig.make(n_robots=6, layout="tiny", horizon=60, task="lifelong")
    batch = EpisodeBatch(env, 3, batch_rng(0, 1, 0))
    core = batch.core
    pickups, stations = task_cells(core.layout)
    rng = np.random.default_rng(0)
    arrivals = 0
    while batch.running:
        # walk towards the goal when a move reduces the distance, else at random
        nxt = core.layout.next_cell[core.pos]
        best = core.distances_to_goal(nxt).argmin(axis=-1)
        acts = np.where(rng.random(core.pos.shape) < 0.8, best, rng.integers(0, N_ACTIONS, core.pos.shape))
        before = core.goal.copy()
        res = core.step(acts)
        arrivals += int(res.reached.sum())
        assert not core.done.any() and not res.terminated.any()
        changed = core.goal != before
        assert np.array_equal(changed, res.reached)  # a new goal exactly on arrival
        assert not (core.goal == core.pos).any()
        new = core.goal[res.reached]
        was = before[res.reached]
        assert np.isin(new[np.isin(was, pickups)], stations).all()  # pickup, then delivery
        fresh = distance_cache(core.layout).fields(core.goal.reshape(-1))  # (B N, F), from scratch
        assert np.array_equal(core.dist.reshape(-1), fresh[np.arange(fresh.shape[0]), core.pos.reshape(-1)])
        near = core.layout.next_cell[core.pos]  # every field, not only at the robots' cells
        assert np.array_equal(core.distances_to_goal(near),
                              fresh.reshape(*core.pos.shape, -1)[np.arange(3)[:, None, None],
                                                                 np.arange(6)[None, :, None], near])
        assert (res.goal_bonus[res.reached] > 0).all()
    assert core.t == 60 and arrivals > 6


def test_core__lifelong_needs_a_task_stream():
    env = EnvConfig.make(n_robots=2, layout="tiny", task="lifelong")
    with pytest.raises(BenchError, match="task stream"):
        WarehouseCore(env).reset(np.array([[0, 1]]), np.array([[2, 3]]))


def test_task_stream__an_episode_does_not_depend_on_its_batch():
    env = EnvConfig.make(n_robots=5, layout="wh20", horizon=30, task="lifelong")
    goals = []
    for size in (2, 4):
        batch = EpisodeBatch(env, size, batch_rng(3, 1, 0))
        goals.append([batch.core.tasks.next_goals(np.ones((size, 5), bool), batch.core.pos)[:5]
                      for _ in range(3)] if batch.core.tasks else None)
    assert goals[0] is not None and goals[1] is not None
    # episode 0's stream is the same in a batch of 2 and of 4 (its own generator)
    assert all(np.array_equal(a, b) for a, b in zip(goals[0], goals[1], strict=True))


def test_pettingzoo__lifelong_passes_the_api_test_and_truncates_at_the_horizon():
    parallel_api_test(parallel_env(n_robots=6, layout="tiny", horizon=25, task="lifelong"), num_cycles=30)
    env = parallel_env(n_robots=4, layout="tiny", horizon=20, task="lifelong")
    env.reset(seed=1)
    steps = 0
    while env.agents:
        _, _, term, trunc, _ = env.step({a: int(env.action_space(a).sample()) for a in env.agents})
        steps += 1
        assert not any(term.values())
    assert steps == 20 and all(trunc.values())


def test_pibt__keeps_planning_new_goals_without_collisions():
    env = EnvConfig.make(n_robots=40, layout=MAP, horizon=60, loss_p=0.3, task="lifelong")
    rows = method_class("pibt")(env, {"eval_chunk": 2}, seed=0).evaluate(0)
    for row in rows:
        assert row["steps"] == 60 and row["collision_rate"] == 0.0
        assert row["throughput"] > 0.1  # several goals per step's worth of arrivals
        assert np.isnan(row["csr"]) and row["success_rate"] == 0.0
