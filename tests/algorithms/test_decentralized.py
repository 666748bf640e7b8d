"""Decentralized baseline: all-to-all payload, stale messages under loss, message maps, learning.

Runtime: about 3 s for the unit tests; the learning test about 10 s on one core.
"""
from __future__ import annotations

import numpy as np
import pytest
import torch

from algorithms.common.all_to_all import OFF_FLOOR, AllToAllBoard
from algorithms.common.episodes import EpisodeBatch, batch_rng
from algorithms.common.execution import ActionChoice
from algorithms.common.trainer import policy_gradient_losses
from algorithms.decentralized import DecentralizedMethod, action_feature_index
from envs.actions import DELTAS, Action
from envs.channel import LossProcess
from envs.config import EnvConfig
from envs.core import WarehouseCore
from envs.layouts import from_ascii
from envs.observations import action_progress
from envs.scenarios import validate_scenario
from tests.algorithms.learning import eval_success

ENV = EnvConfig(n_robots=6, layout="tiny", horizon=20, groups=2, loss_p=0.3)


def test_payload_is_all_to_all_every_step() -> None:
    rows = DecentralizedMethod(ENV, {"eval_chunk": 3}, seed=0).evaluate(0)
    n, d_m = ENV.n_robots, ENV.d_m
    assert [r["payload_scalars_per_step"] for r in rows] == [n * (n - 1) * d_m] * 3
    assert all(r["payload_dec_per_step"] == r["payload_scalars_per_step"] for r in rows)


def run_steps(loss_p: float, steps: int = 6):
    env = EnvConfig(**{**ENV.model_dump(), "loss_p": loss_p})
    m = DecentralizedMethod(env, {}, seed=0)
    choice = ActionChoice.train(m.torch_gen)
    batch = EpisodeBatch(env, 2, batch_rng(0, 0, 0), m.layout)
    starts = batch.core.pos.copy()
    with torch.no_grad():
        state = m.begin(batch, choice)
        for _ in range(steps):
            m.observe(batch, state, batch.core.step(m.decide(batch, state, choice).actions))
    state.board.receive()  # the messages of the current step
    return batch.core, state.board, starts


def test_with_every_message_lost_receivers_hold_only_the_initial_messages() -> None:
    core, board, starts = run_steps(loss_p=1.0)
    n = ENV.n_robots
    off = ~np.eye(n, dtype=bool)
    assert not np.array_equal(core.pos, starts)  # robots did move
    initial = np.broadcast_to(starts[:, None, :], board.pos.shape)
    assert np.array_equal(board.pos[:, off], initial[:, off])  # start positions only
    assert (board.ctl[:, off] == Action.WAIT).all()
    assert (board.age[:, off] == 7).all()  # never refreshed since reset
    # A robot always knows its own current state.
    assert np.array_equal(np.diagonal(board.pos, axis1=1, axis2=2), core.pos)


def test_without_loss_receivers_hold_the_current_messages() -> None:
    core, board, _ = run_steps(loss_p=0.0)
    assert np.array_equal(board.pos, np.broadcast_to(core.pos[:, None, :], board.pos.shape))
    assert (board.age == 0).all()


def make_board(floor: str, starts: list, goals: list, radius: int = 1) -> AllToAllBoard:
    layout = from_ascii(floor)
    core = WarehouseCore(EnvConfig.make(n_robots=len(starts), groups=1, loss_p=1.0), layout)
    s, g = validate_scenario(layout, len(starts), starts, goals)
    core.reset(s[None], g[None])
    n = len(starts)
    return AllToAllBoard(core, LossProcess((1, n, n), 1.0, np.random.default_rng(0)), radius)


def test_message_maps__hand_example() -> None:
    board = make_board(".....\n.....\n.....", [(1, 1), (1, 2), (0, 4)], [(2, 4), (2, 0), (0, 0)])
    board.ctl[0, 0, 1] = int(Action.LEFT)  # robot 0 last heard robot 1 moving Left
    board.age[0, 0, 1] = 5
    maps = board.features().reshape(1, 3, 3, 3, 3)  # (B, N, channel, row, col)
    here, projected, stale = maps[0, 0]
    assert here.tolist() == [[0, 0, 0], [0, 0, 1], [0, 0, 0]]  # robot 2 is outside the window
    assert projected.tolist() == [[0, 0, 0], [0, 1, 0], [0, 0, 0]]  # heading into robot 0
    assert np.allclose(stale, here * 0.5)  # age 5 of a cap of 10
    # Robot 1 at (1, 2) sees robot 0 to its left and robot 2 out of range (0, 4).
    assert maps[0, 1, 0].tolist() == [[0, 0, 0], [1, 0, 0], [0, 0, 0]]


def test_message_maps__drop_robots_that_left_the_floor() -> None:
    board = make_board(".....\n.....\n.....", [(1, 1), (1, 2)], [(2, 4), (2, 0)])
    board.ctl[0, 0, 1] = OFF_FLOOR
    assert board.features()[0, 0].sum() == 0


def test_safety_filter_with_fresh_messages_prevents_every_collision() -> None:
    env = EnvConfig(n_robots=10, layout="tiny", horizon=30, groups=2, loss_p=0.0)
    params = {"eval_chunk": 4}
    free = DecentralizedMethod(env, params, seed=0).evaluate(0, execution="sample")
    assert sum(r["collision_rate"] for r in free) > 0  # untrained robots do collide
    assert all(np.isnan(r["mean_candidates"]) for r in free)  # no filter, no counts
    safe = DecentralizedMethod(env, {**params, "safety_filter": True}, seed=0).evaluate(0, execution="sample")
    assert all(r["collision_rate"] == 0 for r in safe)
    assert all(r["correction_rate"] > 0 and r["mean_candidates"] >= 1 for r in safe)
    assert all(0 <= r["fallback_rate"] <= 1 for r in safe)


def test_action_aligned_features_are_progress_and_sensed_and_received_robots_on_each_target_cell() -> None:
    env = EnvConfig(n_robots=12, layout="tiny", horizon=20, groups=2, loss_p=0.5)
    m = DecentralizedMethod(env, {}, seed=0)
    choice = ActionChoice.train(m.torch_gen)
    batch = EpisodeBatch(env, 2, batch_rng(0, 0, 3), m.layout)
    with torch.no_grad():
        state = m.begin(batch, choice)
        for _ in range(4):  # some stale messages by now
            m.observe(batch, state, batch.core.step(m.decide(batch, state, choice).actions))
    core, board = batch.core, state.board
    board.receive()
    phi = m.observe_robots(state)[..., action_feature_index(m.params.patch_radius)]  # (B, N, 4, 5)
    assert np.array_equal(phi[:, :, 0], action_progress(core))
    cells = core.layout.cells
    target = cells[core.pos][:, :, None, :] + DELTAS  # (B, N, 5, 2) cell each action aims at
    others = cells[board.pos]  # (B, N_recv, N_send, 2) received positions
    heading = cells[core.layout.next_cell[board.pos, np.minimum(board.ctl, 4)]]
    off = ~np.eye(env.n_robots, dtype=bool)[None, :, :, None]
    on_floor = (board.ctl != OFF_FLOOR)[..., None]
    sensed = np.broadcast_to(cells[core.pos][:, None], others.shape)  # true cells, every robot
    sensed_on = np.broadcast_to(core.occupying[:, None, :, None], on_floor.shape)
    for ch, where, floor in ((1, sensed, sensed_on), (2, others, on_floor), (3, heading, on_floor)):
        hits = (where[:, :, None, :, :] == target[:, :, :, None, :]).all(-1)  # (B, N, 5, N)
        expected = (hits & off.transpose(0, 1, 3, 2) & floor.transpose(0, 1, 3, 2)).sum(-1)
        assert np.array_equal(phi[:, :, ch], expected), ch
    assert phi[:, :, 1].sum() > 0 and phi[:, :, 2].sum() > 0  # the comparison is not vacuous


def test_update__chunked_actor_loss_is_the_papers_loss_with_the_same_gradient() -> None:
    env = EnvConfig(n_robots=6, layout="tiny", horizon=20, groups=2, loss_p=0.3)

    def rolled(chunk_rows: int) -> tuple[DecentralizedMethod, object]:
        m = DecentralizedMethod(env, {"batch_episodes": 3, "chunk_rows": chunk_rows}, seed=2)
        with torch.no_grad():
            state, _ = m.run(EpisodeBatch(env, 3, batch_rng(0, 0, 0), m.layout), ActionChoice.train(m.torch_gen))
        return m, state

    small, state_small = rolled(256)  # about 360 robot-steps: two chunks
    whole, state_whole = rolled(100_000)
    buf = state_whole.buffer
    # The paper's loss (eq:losses) on the same batch, before any update.
    with torch.no_grad():
        logits = whole.actor(buf.tensor("obs"), buf.tensor("mask"))
        logp = torch.log_softmax(logits, -1).gather(-1, buf.tensor("actions")[..., None])[..., 0]
        logp_team = (logp * buf.tensor("active")).sum(-1)  # (T, B): sum over robots
        values = whole.critic(buf.tensor("critic"), buf.tensor("t_frac"))
    ref = policy_gradient_losses(logp_team, values, buf.rewards[: buf.t], buf.running[: buf.t])
    out_small, out_whole = small.update(state_small), whole.update(state_whole)
    assert np.isclose(out_whole["actor_loss"], float(ref.actor), rtol=1e-4, atol=1e-6)
    assert np.isclose(out_small["actor_loss"], out_whole["actor_loss"], rtol=1e-4, atol=1e-6)
    for a, b in zip(small.actor.parameters(), whole.actor.parameters(), strict=True):
        assert torch.allclose(a, b, atol=1e-6)


@pytest.mark.slow
def test_decentralized__learns_on_a_small_layout() -> None:
    env = EnvConfig(n_robots=6, layout="tiny", horizon=40, groups=2, loss_p=0.2)
    m = DecentralizedMethod(env, {"batch_episodes": 8, "eval_chunk": 20}, seed=0)

    before = eval_success(m)
    for _ in range(200):
        m.train_iteration()
    after = eval_success(m)
    # Seed 0 on one torch thread (shared defaults, robots in view): argmax success 0.00 -> 0.95.
    assert after >= before + 0.4, (before, after)
