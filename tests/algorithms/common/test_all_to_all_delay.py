"""The decentralized baseline's board over a delayed channel: with a zero-step delay line
it holds what the plain board holds; with a fixed delay d every receiver holds the
messages of d steps ago, aged d."""
from __future__ import annotations

import numpy as np

from algorithms.common.all_to_all import AllToAllBoard
from algorithms.common.episodes import EpisodeBatch, batch_rng
from envs.actions import N_ACTIONS
from envs.channel import DelayLine
from envs.config import EnvConfig


def _walk(batch: EpisodeBatch, rng: np.random.Generator) -> None:
    batch.core.step(rng.integers(0, N_ACTIONS, size=batch.core.pos.shape))


def test_board__a_zero_step_delay_line_holds_what_the_plain_board_holds() -> None:
    env = EnvConfig.make(n_robots=10, layout="tiny", horizon=30, loss_p=0.5, loss_model="gilbert_elliott")
    plain_batch = EpisodeBatch(env, 2, batch_rng(1, 0, 0))
    late_batch = EpisodeBatch(env, 2, batch_rng(1, 0, 0))
    plain = AllToAllBoard(plain_batch.core, plain_batch.open_channel("robots"), 1)
    chan = late_batch.open_channel("robots")
    chan.delay = DelayLine((2, 10, 10), 0, "fixed", 0, None)
    late = AllToAllBoard(late_batch.core, chan, 1)
    walk_a, walk_b = np.random.default_rng(0), np.random.default_rng(0)
    for _ in range(20):
        assert np.array_equal(plain.receive(), late.receive())
        for name in ("pos", "ctl", "age"):
            assert np.array_equal(getattr(plain, name), getattr(late, name)), name
        assert np.array_equal(plain.features(), late.features())
        _walk(plain_batch, walk_a)
        _walk(late_batch, walk_b)


def test_board__fixed_delay_holds_the_positions_of_d_steps_ago() -> None:
    d = 3
    env = EnvConfig.make(n_robots=8, layout="tiny", horizon=30, loss_p=0.0, delay=d)
    batch = EpisodeBatch(env, 2, batch_rng(2, 0, 0))
    board = AllToAllBoard(batch.core, batch.open_channel("robots"), 1)
    starts = batch.core.pos.copy()
    history, walk = [], np.random.default_rng(3)
    others = ~board.eye[None]
    for t in range(12):
        history.append(batch.core.pos.copy())
        board.receive()
        want = history[t - d] if t >= d else starts
        held = np.broadcast_to(want[:, None, :], board.pos.shape)
        assert np.array_equal(board.pos[np.broadcast_to(others, held.shape)],
                              held[np.broadcast_to(others, held.shape)]), t
        assert (board.age[np.broadcast_to(others, board.age.shape)] == (d if t >= d else t + 1)).all()
        assert (board.age[:, board.eye] == 0).all()
        _walk(batch, walk)
