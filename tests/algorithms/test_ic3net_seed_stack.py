"""Seed stacking of IC3Net (algorithms/common/seed_stack.py, ``IC3NetMethod.stack_view``):
S seeds of one configuration trained with their rollouts in one batch give, bit for bit,
what each seed gives trained alone: training rows, parameters, optimizer states and
generator states. Each seed's policy runs its own episodes with its own rows of the LSTM
state and its own gate samples; under ``protocol="mappo"`` each seed replays from its own
rows of the LSTM states kept at chunk starts."""
from __future__ import annotations

import pytest

from algorithms.ic3net import IC3NetMethod
from envs.config import EnvConfig
from tests.algorithms.hierarchical.test_seed_stack import assert_stacked_is_alone
from tests.algorithms.test_decentralized_seed_stack import _env, assert_ahead_and_early_end_is_alone

TINY = {"layout": "tiny", "n_robots": 6, "horizon": 30}


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
    """Seed 2 is one update ahead; seed 0's one robot arrives at step 65 of 80 while seed 2's
    episode runs to the horizon: seed 0 draws no more actions or gates and updates from its
    own 65 steps, then trains on identically."""
    env = _env(layout="tiny", n_robots=1, horizon=80, loss_p=0.2)
    rows_alone = assert_ahead_and_early_end_is_alone(lambda: _methods(env, [0, 2], batch_episodes=1, **params))
    assert [rows[0]["steps"] for rows in rows_alone] == [65, 80]  # the early end happens


def test_stack_view__refuses_methods_that_differ_in_more_than_the_seed() -> None:
    env = _env()
    with pytest.raises(ValueError, match="differ only in their seed"):
        IC3NetMethod.stack_view(_methods(env, [0]) + _methods(env, [1], lr=1e-4))
