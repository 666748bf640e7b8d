"""Seed stacking (algorithms/common/seed_stack.py): S cells of one configuration trained with
their rollouts in one batch give, bit for bit, what each cell gives trained alone: the same
training rows, parameters, optimizer states and generator states, whatever it is stacked
with and whatever progress the others have."""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
import torch

from algorithms.common.episodes import EpisodeBatch, batch_rng
from algorithms.common.seed_stack import (
    StackedBatch,
    StackedChoice,
    StackedRNG,
    split_buffer,
    train_stacked,
)
from algorithms.common.trainer import RolloutBuffer
from algorithms.hierarchical.method import HierarchicalMethod
from envs.config import EnvConfig

MAP = "warehouse-10-20-10-2-1"


def _env(**kw) -> EnvConfig:
    base = dict(n_robots=24, layout=MAP, horizon=40, loss_p=0.3, groups=4)
    return EnvConfig.make(**{**base, **kw})


def _methods(env: EnvConfig, seeds: list[int], **params) -> list[HierarchicalMethod]:
    return [HierarchicalMethod(env, {"batch_episodes": 3, **params}, seed=s) for s in seeds]


def _fingerprint(m: HierarchicalMethod, rows: list[dict]) -> tuple:
    rows = [{k: v for k, v in r.items() if k != "wall_s"} for r in rows]
    tensors = [t.detach().clone() for mod in m.modules().values() if isinstance(mod, torch.nn.Module)
               for t in mod.state_dict().values()]
    opt = [(k, v) for name, mod in m.modules().items() if isinstance(mod, torch.optim.Optimizer)
           for k, v in sorted(mod.state_dict()["state"].items())]
    return rows, tensors, opt, m.torch_gen.get_state(), m.iterations, m.episodes_done


def _same(a: tuple, b: tuple) -> None:
    rows_a, ten_a, opt_a, gen_a, it_a, ep_a = a
    rows_b, ten_b, opt_b, gen_b, it_b, ep_b = b
    assert (it_a, ep_a) == (it_b, ep_b)
    assert len(rows_a) == len(rows_b)
    for ra, rb in zip(rows_a, rows_b, strict=True):
        assert ra.keys() == rb.keys()
        for k in ra:
            assert ra[k] == rb[k] or (ra[k] != ra[k] and rb[k] != rb[k]), (k, ra[k], rb[k])  # NaN == NaN
    assert all(torch.equal(x, y) for x, y in zip(ten_a, ten_b, strict=True))
    for (ka, sa), (kb, sb) in zip(opt_a, opt_b, strict=True):
        assert ka == kb and all(torch.equal(sa[f], sb[f]) for f in sa if isinstance(sa[f], torch.Tensor))
    assert torch.equal(gen_a, gen_b)


@pytest.mark.parametrize("kw, params", [
    ({}, {}),
    ({}, {"protocol": "mappo"}),  # decision 0220's levels normalized apart, critic on minibatches
    ({"layout": "tiny", "n_robots": 6, "on_goal": "stay", "horizon": 30}, {"messages": "oracle", "ref_hold": 3}),
    ({}, {"share_params": True}),  # one set of weights per seed, repeated over the groups
    ({"layout": "tiny", "n_robots": 6, "on_goal": "stay", "horizon": 30},
     {"share_params": True, "fallback": "per_robot", "ref_lr": 1e-3}),
    ({"layout": "tiny", "n_robots": 6, "horizon": 30, "task": "lifelong", "delay": 1.5,
      "delay_model": "geometric"}, {}),
])
def test_stacked_training__is_bit_for_bit_each_seed_trained_alone(kw, params) -> None:
    env = _env(**kw)
    assert_stacked_is_alone(lambda: _methods(env, [3, 4, 5], **params))


def assert_stacked_is_alone(make: Callable[[], list], iterations: int = 2) -> None:
    """The methods ``make()`` builds, trained ``iterations`` times alone and (built again)
    seed-stacked through one ``stack_view``: each seed bit for bit."""
    alone = make()
    rows_alone = [[r for _ in range(iterations) for r in m.train_iteration()] for m in alone]
    stacked = make()
    view = type(stacked[0]).stack_view(stacked)
    rows_stacked: list[list[dict]] = [[] for _ in stacked]
    for _ in range(iterations):
        for k, rows in enumerate(train_stacked(stacked, view)):
            rows_stacked[k] += rows
    for m_a, r_a, m_s, r_s in zip(alone, rows_alone, stacked, rows_stacked, strict=True):
        _same(_fingerprint(m_a, r_a), _fingerprint(m_s, r_s))


def test_stacked_training__seeds_at_different_progress() -> None:
    """A stack may mix cells at different iterations (a resumed cell beside a fresh one)."""
    env = _env()
    alone = _methods(env, [0, 1])
    alone[1].train_iteration()  # seed 1 is one update ahead
    rows_alone = [m.train_iteration() for m in alone]
    stacked = _methods(env, [0, 1])
    stacked[1].train_iteration()
    for m_a, r_a, m_s, r_s in zip(alone, rows_alone, stacked, train_stacked(stacked), strict=True):
        _same(_fingerprint(m_a, r_a), _fingerprint(m_s, r_s))


def test_stacked_training__a_seed_whose_episodes_end_early_stops_as_alone() -> None:
    """Seed 2's first episode ends at step 68 of 80, seed 0's runs to the horizon: seed 2
    draws no more actions and updates from its own 68 steps, then trains on identically."""
    env = _env(layout="tiny", n_robots=2, groups=2, horizon=80, loss_p=0.2)
    alone = _methods(env, [2, 0], batch_episodes=1)
    rows_alone = [[r for _ in range(2) for r in m.train_iteration()] for m in alone]
    assert [rows[0]["steps"] for rows in rows_alone] == [68, 80]  # the early end happens
    stacked = _methods(env, [2, 0], batch_episodes=1)
    rows_stacked = [a + b for a, b in zip(train_stacked(stacked), train_stacked(stacked), strict=True)]
    for m_a, r_a, m_s, r_s in zip(alone, rows_alone, stacked, rows_stacked, strict=True):
        _same(_fingerprint(m_a, r_a), _fingerprint(m_s, r_s))


def test_stacked_rng__each_part_draws_its_own_rows() -> None:
    a, b = np.random.default_rng(1), np.random.default_rng(2)
    got = StackedRNG([np.random.default_rng(1), np.random.default_rng(2)], [2, 3]).random((5, 4))
    assert np.array_equal(got, np.concatenate([a.random((2, 4)), b.random((3, 4))]))
    with pytest.raises(ValueError, match="5 stacked episodes"):
        StackedRNG([a, b], [2, 3]).random((4, 4))


def test_stacked_choice__samples_each_slice_with_its_generator_and_skips_ended_seeds() -> None:
    env = _env(layout="tiny", n_robots=4)
    parts = [EpisodeBatch(env, 2, batch_rng(s, 0, 0)) for s in (0, 1)]
    batch = StackedBatch(parts)
    logits = torch.randn(3, 4, 4, 5)
    gens = [torch.Generator().manual_seed(7), torch.Generator().manual_seed(8)]
    ref0, ref1 = torch.Generator().manual_seed(7), torch.Generator().manual_seed(8)
    got = StackedChoice(gens, batch)(logits)
    from algorithms.common.execution import sample_categorical
    assert torch.equal(got[:, :2], sample_categorical(logits[:, :2].contiguous(), 1.0, ref0))
    assert torch.equal(got[:, 2:], sample_categorical(logits[:, 2:].contiguous(), 1.0, ref1))
    batch.core.ended[2:] = True  # seed 1 has stopped: no draw, its generator unmoved
    state = gens[1].get_state()
    StackedChoice(gens, batch)(logits)
    assert torch.equal(gens[1].get_state(), state)


def test_split_buffer__a_part_lasts_until_its_last_episode_ended() -> None:
    buf = RolloutBuffer(5, 4, {"x": ((2,), np.float32)})
    for t in range(4):
        buf.add(x=np.full((4, 2), t, np.float32))
        buf.reward(np.zeros(4, np.float32), np.array([t < 2, t < 1, True, t < 3]))
    first, second = split_buffer(buf, 0, 2), split_buffer(buf, 2, 4)
    assert (first.t, second.t) == (2, 4)
    assert first.data["x"].flags.c_contiguous and first.data["x"].shape == (5, 2, 2)


def test_stack_view__refuses_methods_that_differ_in_more_than_the_seed() -> None:
    env = _env()
    with pytest.raises(ValueError, match="differ only in their seed"):
        HierarchicalMethod.stack_view(_methods(env, [0]) + _methods(env, [1], lr=1e-4))
    with pytest.raises(ValueError, match="differ only in their seed"):
        HierarchicalMethod.stack_view(_methods(env, [0], share_params=True) + _methods(env, [1]))


def test_train_stacked__one_method_is_its_own_iteration_and_wall_times_add_up() -> None:
    """A stack of one is the method's ``train_iteration``; in a stack of three every row's
    wall time is positive and the rows' total is the iteration's elapsed time (the shared
    rollout counted once, split among the seeds, plus each update)."""
    import time

    env = _env(horizon=20)
    alone, single = _methods(env, [4]), _methods(env, [4])
    _same(_fingerprint(alone[0], alone[0].train_iteration()),
          _fingerprint(single[0], train_stacked(single)[0]))
    stacked = _methods(env, [0, 1, 2])
    t0 = time.perf_counter()
    rows = [r for part in train_stacked(stacked) for r in part]
    elapsed = time.perf_counter() - t0
    walls = [r["wall_s"] for r in rows]
    assert min(walls) > 0 and 0.5 * elapsed < sum(walls) <= elapsed
