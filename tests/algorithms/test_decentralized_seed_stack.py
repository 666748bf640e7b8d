"""Seed stacking of the decentralized baseline (algorithms/common/seed_stack.py,
``DecentralizedMethod.stack_view``): S seeds of one configuration trained with their
rollouts in one batch give, bit for bit, what each seed gives trained alone: training rows,
parameters, optimizer states and generator states."""
from __future__ import annotations

from collections.abc import Callable

import pytest

from algorithms.common.seed_stack import train_stacked
from algorithms.decentralized import DecentralizedMethod
from envs.config import EnvConfig
from tests.algorithms.hierarchical.test_seed_stack import _fingerprint, _same, assert_stacked_is_alone

MAP = "warehouse-10-20-10-2-1"


def _env(**kw) -> EnvConfig:
    base = dict(n_robots=24, layout=MAP, horizon=40, loss_p=0.3)
    return EnvConfig.make(**{**base, **kw})


def _methods(env: EnvConfig, seeds: list[int], **params) -> list[DecentralizedMethod]:
    return [DecentralizedMethod(env, {"batch_episodes": 3, **params}, seed=s) for s in seeds]


@pytest.mark.parametrize("kw, params", [
    ({}, {}),
    ({}, {"protocol": "mappo"}),
    ({"layout": "tiny", "n_robots": 6, "on_goal": "stay", "horizon": 30}, {"safety_filter": True}),
    ({"layout": "tiny", "n_robots": 6, "horizon": 30, "task": "lifelong", "delay": 1.5,
      "delay_model": "geometric"}, {"action_path": False}),
])
def test_stacked_training__is_bit_for_bit_each_seed_trained_alone(kw, params) -> None:
    env = _env(**kw)
    assert_stacked_is_alone(lambda: _methods(env, [3, 4, 5], **params))


def test_stacked_training__seeds_at_different_progress_and_an_early_end() -> None:
    """Seed 2 is one update ahead; seed 0's one robot arrives at step 62 of 80 while seed 2's
    episode runs to the horizon: seed 0 draws no more actions and updates from its own 62
    steps, then trains on identically."""
    env = _env(layout="tiny", n_robots=1, horizon=80, loss_p=0.2)
    rows_alone = assert_ahead_and_early_end_is_alone(lambda: _methods(env, [0, 2], batch_episodes=1))
    assert [rows[0]["steps"] for rows in rows_alone] == [62, 80]  # the early end happens


def assert_ahead_and_early_end_is_alone(make: Callable[[], list]) -> list[list[dict]]:
    """The two methods ``make()`` builds, the second one update ahead, trained 2 updates alone
    and (built again) stacked: each bit for bit. Returns the rows alone."""
    alone = make()
    alone[1].train_iteration()
    rows_alone = [[r for _ in range(2) for r in m.train_iteration()] for m in alone]
    stacked = make()
    stacked[1].train_iteration()
    rows_stacked = [a + b for a, b in zip(train_stacked(stacked), train_stacked(stacked), strict=True)]
    for m_a, r_a, m_s, r_s in zip(alone, rows_alone, stacked, rows_stacked, strict=True):
        _same(_fingerprint(m_a, r_a), _fingerprint(m_s, r_s))
    return rows_alone


def test_stack_view__refuses_methods_that_differ_in_more_than_the_seed() -> None:
    env = _env()
    with pytest.raises(ValueError, match="differ only in their seed"):
        DecentralizedMethod.stack_view(_methods(env, [0]) + _methods(env, [1], lr=1e-4))
