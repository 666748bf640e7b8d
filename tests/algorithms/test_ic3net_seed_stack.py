"""Seed stacking of IC3Net (algorithms/common/seed_stack.py, ``IC3NetMethod.stack_view``):
S seeds of one configuration trained with their rollouts in one batch give, bit for bit,
what each seed gives trained alone: training rows, parameters, optimizer states and
generator states. Each seed's policy runs its own episodes with its own rows of the LSTM
state and its own gate samples; under ``protocol="mappo"`` each seed replays from its own
rows of the LSTM states kept at chunk starts."""
from __future__ import annotations

import pytest

from algorithms.common.seed_stack import train_stacked
from algorithms.ic3net import IC3NetMethod
from envs.config import EnvConfig
from tests.algorithms.hierarchical.test_seed_stack import _fingerprint, _same, assert_stacked_is_alone

MAP = "warehouse-10-20-10-2-1"
TINY = {"layout": "tiny", "n_robots": 6, "horizon": 30}


def _env(**kw) -> EnvConfig:
    base = dict(n_robots=24, layout=MAP, horizon=40, loss_p=0.3)
    return EnvConfig.make(**{**base, **kw})


def _methods(env: EnvConfig, seeds: list[int], **params) -> list[IC3NetMethod]:
    return [IC3NetMethod(env, {"batch_episodes": 3, **params}, seed=s) for s in seeds]


@pytest.mark.parametrize("kw, params", [
    ({}, {"detach_gap": 15}),  # paper protocol, the replay in three chunks
    ({}, {"protocol": "mappo", "detach_gap": 15}),  # replays from each seed's kept chunk states
    ({}, {"protocol": "mappo", "credit": "team", "gate": "open", "comm_passes": 2}),
    ({**TINY, "on_goal": "stay"}, {"baseline": "per_robot", "optimizer": "rmsprop"}),  # own value normalizer
    ({**TINY, "task": "lifelong", "delay": 1.5, "delay_model": "geometric"}, {}),
])
def test_stacked_training__is_bit_for_bit_each_seed_trained_alone(kw, params) -> None:
    env = _env(**kw)
    assert_stacked_is_alone(lambda: _methods(env, [3, 4, 5], **params))


@pytest.mark.parametrize("params", [{}, {"protocol": "mappo", "detach_gap": 25}])
def test_stacked_training__seeds_at_different_progress_and_an_early_end(params) -> None:
    """Seed 2 is one update ahead; seed 0's one robot arrives at step 62 of 80 while seed 2's
    episode runs to the horizon: seed 0 draws no more actions or gates and updates from its
    own 62 steps, then trains on identically."""
    env = _env(layout="tiny", n_robots=1, horizon=80, loss_p=0.2)
    alone = _methods(env, [0, 2], batch_episodes=1, **params)
    alone[1].train_iteration()
    rows_alone = [[r for _ in range(2) for r in m.train_iteration()] for m in alone]
    assert rows_alone[0][0]["steps"] < 80 == rows_alone[1][0]["steps"]  # the early end happens
    stacked = _methods(env, [0, 2], batch_episodes=1, **params)
    stacked[1].train_iteration()
    rows_stacked = [a + b for a, b in zip(train_stacked(stacked), train_stacked(stacked), strict=True)]
    for m_a, r_a, m_s, r_s in zip(alone, rows_alone, stacked, rows_stacked, strict=True):
        _same(_fingerprint(m_a, r_a), _fingerprint(m_s, r_s))


def test_stack_view__refuses_methods_that_differ_in_more_than_the_seed() -> None:
    env = _env()
    with pytest.raises(ValueError, match="differ only in their seed"):
        IC3NetMethod.stack_view(_methods(env, [0]) + _methods(env, [1], lr=1e-4))
