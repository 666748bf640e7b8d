"""Shared episode loop and per-episode metrics (EpisodeStats)."""
from __future__ import annotations

import numpy as np
import pandas as pd

from algorithms.base import Method
from algorithms.common.episodes import Decision, EpisodeBatch, EpisodeStats, batch_rng
from envs import EnvConfig
from envs.core import StepResult


def _result(b: int, n: int, **over) -> StepResult:
    z = np.zeros((b, n))
    base = dict(reward=np.zeros(b), progress=z, goal_bonus=z, collision_penalty=z,
                time_penalty=z, collision=z.astype(bool), invalid=z.astype(bool),
                reached=z.astype(bool), active=np.ones((b, n), bool),
                terminated=np.zeros(b, bool), truncated=np.zeros(b, bool))
    base.update(over)
    return StepResult(**base)


def test_episode_stats__rates_are_per_active_robot_step_and_per_group_step():
    stats = EpisodeStats(batch=1, n_robots=4, d_m=3)
    coll = np.array([[True, False, False, False]])
    act = np.array([[True, True, True, False]])  # robot 3 already finished
    dec = Decision(actions=np.array([[4, 0, 1, 4]]), proposed=np.array([[0, 0, 1, 2]]),
                   candidates=np.array([6.0]), filter_calls=np.array([2.0]),
                   fallbacks=np.array([1.0]), pred_sq_err=np.array([8.0]),
                   pred_count=np.array([2.0]), payload=36.0)
    stats.add(np.array([True]), _result(1, 4, collision=coll, active=act, reward=np.array([1.5])), dec)
    stats.add(np.array([False]), _result(1, 4, active=np.zeros((1, 4), bool)), dec)  # ended
    row = stats.finish(np.array([[True, False, True, True]]))[0]
    assert row["team_return"] == 1.5
    assert row["success_rate"] == 0.75
    assert row["collision_rate"] == 1 / 3
    assert row["correction_rate"] == 1 / 3  # robot 0 changed; robot 3 not active
    assert row["mean_candidates"] == 3.0 and row["fallback_rate"] == 0.5
    assert row["predictor_error"] == 4.0
    assert row["payload_scalars_per_step"] == 36.0  # the ended step does not count
    assert row["payload_dec_per_step"] == 4 * 3 * 3
    assert row["steps"] == 1


class _Random(Method):
    name = "random-test"
    learned = False

    def begin(self, batch, choice):
        return np.random.default_rng(0)

    def decide(self, batch, state, choice):
        return Decision(actions=state.integers(0, 5, batch.core.pos.shape))


def test_evaluate__chunks_are_reproducible_and_numbered():
    cfg = EnvConfig(n_robots=6, layout="tiny", horizon=30)
    m = _Random(cfg, {"eval_chunk": 3}, seed=7)
    a, b = m.evaluate(1), m.evaluate(1)
    assert pd.DataFrame(a).equals(pd.DataFrame(b))  # NaN-aware equality
    assert [r["episode"] for r in a] == [3, 4, 5]
    assert not pd.DataFrame(m.evaluate(0)).drop(columns='episode').equals(
        pd.DataFrame(a).drop(columns='episode'))


def test_episode_batch__scenarios_depend_only_on_the_generator():
    cfg = EnvConfig(n_robots=6, layout="tiny")
    x = EpisodeBatch(cfg, 4, batch_rng(1, 0, 2)).core
    y = EpisodeBatch(cfg, 4, batch_rng(1, 0, 2)).core
    z = EpisodeBatch(cfg, 4, batch_rng(1, 0, 3)).core
    assert np.array_equal(x.pos, y.pos) and np.array_equal(x.goal, y.goal)
    assert not np.array_equal(x.pos, z.pos)
