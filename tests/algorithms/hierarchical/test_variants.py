"""The hierarchical method's named variants (docs/decisions/0118).

Each variant departs from one line of the paper; each test checks that it does what its
name says and that the default is untouched. Runtime: about 10 s.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import torch

from algorithms.common.episodes import EpisodeBatch, batch_rng
from algorithms.hierarchical.fallback import offenders_wait
from algorithms.hierarchical.method import HierarchicalMethod
from algorithms.hierarchical.safety_filter import SafetyFilter
from envs.actions import WAIT
from envs.config import EnvConfig
from envs.errors import BenchError
from envs.layouts import from_ascii
from tests.algorithms.hierarchical.test_method_properties import rollout
from tests.algorithms.hierarchical.traced import TracedHierarchical

UP, DOWN, LEFT, RIGHT = 0, 1, 2, 3


def dense(loss_p: float = 0.2, horizon: int = 30, **params: object) -> TracedHierarchical:
    env = EnvConfig.make(n_robots=20, layout="wh20", horizon=horizon, loss_p=loss_p)
    return TracedHierarchical(env, {"hidden": 16, "predictor_hidden": 16, "batch_episodes": 3,
                                    "eval_chunk": 4, **params}, seed=1)


# ------------------------------------------------------------ per-robot fallback
def test_offenders_wait__only_offending_robots_wait_and_the_rule_cascades() -> None:
    """A corridor of cells 0..4. A on 0 -> Right, D on 1 -> Right, B on 2 -> Right into 3
    (in a neighbour's reach) and E on 4 -> Up (a wall). B and E offend and wait; then D,
    moving into B's cell, offends; then A, moving into D's: everybody waits (cascade)."""
    layout = from_ascii("@@@@@\n.....\n@@@@@")
    filt = SafetyFilter(layout, 2, 500)
    pos = np.array([[0, 2, 1, 4]])  # A, B, D, E
    prop = np.array([[RIGHT, RIGHT, RIGHT, UP]])
    blocked = np.zeros((1, layout.n_free), bool)
    blocked[0, 3] = True
    on = np.ones((1, 4), bool)
    out = offenders_wait(layout.next_cell, layout.move_valid, pos, on, on, prop, blocked)
    assert out.tolist() == [[WAIT, WAIT, WAIT, WAIT]]
    # Without the cascade source only the offender waits: B blocked, A and D move on.
    pos = np.array([[0, 3, 4]])  # A on 0 -> Right, D on 3 -> Left, B on 4 -> Up (a wall)
    prop = np.array([[RIGHT, LEFT, UP]])
    out = offenders_wait(layout.next_cell, layout.move_valid, pos, on[:, :3], on[:, :3], prop,
                         np.zeros((1, layout.n_free), bool))
    assert out.tolist() == [[RIGHT, LEFT, WAIT]]  # only the robot walking into the wall waits
    # Two robots swapping: both offend, both wait; a third far away keeps its move.
    pos = np.array([[1, 2, 4]])
    prop = np.array([[RIGHT, LEFT, LEFT]])
    out = offenders_wait(layout.next_cell, layout.move_valid, pos, on[:, :3], on[:, :3], prop,
                         filt.blocked_cells(np.zeros((1, 1), np.int64), np.zeros((1, 1), bool)))
    assert out.tolist() == [[WAIT, WAIT, LEFT]]


def test_fallback_variant__keeps_moves_where_joint_wait_stops_the_group() -> None:
    """Same seed and episodes: per_robot executes some moves on group-steps that fell back
    (joint Wait executes none), and the metrics still count those group-steps as fallbacks."""
    joint, per = dense(), dense(fallback="per_robot")
    batch_a = EpisodeBatch(joint.env, 3, batch_rng(2, 0, 0), joint.layout)
    batch_b = EpisodeBatch(per.env, 3, batch_rng(2, 0, 0), per.layout)
    moved = falls = 0
    for (ta, da, *_), (tb, db, *_) in zip(rollout(joint, batch_a, True), rollout(per, batch_b, True), strict=False):
        fb = tb["filter_fallback"]  # (B, Z)
        falls += int(fb.sum())
        moving = db.actions != WAIT  # (B, N)
        per_group = np.stack([moving[:, per.gs.groups == z].any(1) for z in range(4)], axis=1)
        moved += int((per_group & fb).sum())
        fa = ta["filter_fallback"]
        joint_moving = np.stack([(da.actions != WAIT)[:, joint.gs.groups == z].any(1) for z in range(4)], axis=1)
        assert not (joint_moving & fa).any()  # joint Wait: nothing moves in a fallen-back group
    assert falls > 0 and moved > 0


# ------------------------------------------------------------ resample on fallback
def test_resample_on_fallback__fewer_fallbacks_at_argmax_training_untouched() -> None:
    base, var = dense(horizon=40), dense(horizon=40, resample_on_fallback=True)
    ev_base, ev_var = base.evaluate(0), var.evaluate(0)
    fb_base = np.mean([r["fallback_rate"] for r in ev_base])
    fb_var = np.mean([r["fallback_rate"] for r in ev_var])
    assert fb_base > 0 and fb_var < fb_base
    assert pd.DataFrame(ev_var).equals(pd.DataFrame(var.evaluate(0)))  # reproducible (NaN-aware)
    strip = lambda rows: [{k: v for k, v in r.items() if k != "wall_s"} for r in rows]  # noqa: E731
    a, b = dense(), dense(resample_on_fallback=True)
    assert str(strip(a.train_iteration())) == str(strip(b.train_iteration()))  # training samples anyway


# ------------------------------------------------------------ reference variants
def test_no_reference__ref_size_one_gives_a_constant_r_and_no_reference_loss() -> None:
    m = dense(ref_size=1)
    batch = EpisodeBatch(m.env, 2, batch_rng(3, 0, 0), m.layout)
    for k, (tr, *_rest) in enumerate(rollout(m, batch, False)):
        assert (tr["ref"] == 0).all() and torch.equal(tr["ref_logp"], torch.zeros_like(tr["ref_logp"]))
        if k == 3:
            break
    rows = m.train_iteration()
    assert rows[0]["entropy_ref"] == 0.0


def test_ref_hold__r_is_redrawn_every_k_steps_and_mu_learns_only_from_those() -> None:
    m = dense(ref_hold=4, horizon=12)
    batch = EpisodeBatch(m.env, 3, batch_rng(4, 0, 0), m.layout)
    refs = [tr["ref"].clone() for tr, *_rest in rollout(m, batch, False)]
    buf = m._last_state.buffer
    new = buf.data["ref_new"][: buf.t]  # (T, B, Z)
    assert new[0::4].all() and not new[1::4].any() and not new[3::4].any()
    for t in range(len(refs)):
        if t % 4:
            assert torch.equal(refs[t], refs[t - 1])
    assert any(not torch.equal(refs[t], refs[t - 1]) for t in range(4, len(refs), 4))  # redrawn
    # The loss ignores mu on held steps: changing r's log-prob there changes nothing.
    rows_a = dense(ref_hold=4, horizon=12).train_iteration()
    rows_b = dense(ref_hold=1, horizon=12).train_iteration()
    assert rows_a[0]["entropy_ref"] > 0 and rows_a[0]["actor_loss"] != rows_b[0]["actor_loss"]


def test_ref_lr_and_embed_scale() -> None:
    m = dense(ref_lr=0.02, ref_embed_scale=2.0)
    lrs = [g["lr"] for g in m.opt_policy.param_groups]
    assert lrs == [0.02, m.params.lr]
    assert m.opt_policy.param_groups[0]["params"] == list(m.reference.parameters())
    base = dense()
    assert torch.allclose(m.local.ref_embed, base.local.ref_embed * 4.0)  # same draw, std 0.5 -> 2
    assert len(base.opt_policy.param_groups) == 1  # default: the paper's single optimizer


def test_variant_params_are_validated() -> None:
    env = EnvConfig.make(n_robots=8, layout="tiny", horizon=5)
    for bad in ({"messages": "truth"}, {"fallback": "none"}, {"ref_hold": 0}, {"ref_lr": 0.0}):
        with pytest.raises(BenchError, match=next(iter(bad))):
            HierarchicalMethod(env, bad)


def test_ref_advantage_group__group_rewards_sum_to_the_team_reward_and_weigh_mu() -> None:
    m = dense(ref_advantage="group", horizon=15)
    batch = EpisodeBatch(m.env, 3, batch_rng(5, 0, 0), m.layout)
    list(rollout(m, batch, False))
    buf = m._last_state.buffer
    gr = buf.data["group_reward"][: buf.t]
    assert np.allclose(gr.sum(-1), buf.rewards[: buf.t], atol=1e-5)
    assert (np.abs(gr).sum(0) > 0).all()  # every group's share is recorded
    team, group = dense(horizon=15).train_iteration(), dense(ref_advantage="group", horizon=15).train_iteration()
    assert np.isfinite(group[0]["actor_loss"]) and group[0]["actor_loss"] != team[0]["actor_loss"]
    assert group[0]["critic_loss"] == team[0]["critic_loss"]  # only mu's weights change
