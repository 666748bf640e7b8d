"""AllToAllBoard's in-place receive and window-lookup maps equal the plain formulas exactly.

Runtime: about 1 s.
"""
from __future__ import annotations

import numpy as np

from algorithms.common.all_to_all import AGE_CAP, MAP_CHANNELS, OFF_FLOOR, AllToAllBoard
from algorithms.common.episodes import EpisodeBatch, batch_rng
from envs.actions import WAIT
from envs.channel import LossProcess
from envs.config import EnvConfig


def plain_features(board: AllToAllBoard) -> np.ndarray:
    """Row and column offsets of every (receiver, sender) pair, as first written."""
    core, k, side = board.core, board.radius, board.side
    b, n = core.pos.shape
    rows = core.layout.cells[:, 0].astype(np.int32)
    cols = core.layout.cells[:, 1].astype(np.int32)
    valid = (board.ctl != OFF_FLOOR) & board.others
    projected = core.layout.next_cell[board.pos, np.minimum(board.ctl, WAIT)]
    stale = np.minimum(board.age, AGE_CAP).astype(np.float32) * (1.0 / AGE_CAP)
    my_r = (rows[core.pos] - k)[:, :, None]
    my_c = (cols[core.pos] - k)[:, :, None]
    base = np.arange(b * n, dtype=np.int64).reshape(b, n, 1) * (side * side)
    size = b * n * side * side
    out = np.empty((b, n, MAP_CHANNELS, side * side), dtype=np.float32)
    for ch, where in ((0, board.pos), (1, projected)):
        dr = rows[where] - my_r
        dc = cols[where] - my_c
        inside = valid & (dr.view(np.uint32) < side) & (dc.view(np.uint32) < side)
        flat = (base + dr * side + dc)[inside]
        out[:, :, ch] = np.bincount(flat, minlength=size).reshape(b, n, -1)
        if ch == 0:
            out[:, :, 2] = np.bincount(flat, weights=stale[inside], minlength=size).reshape(b, n, -1)
    return out.reshape(b, n, -1)


def test_features_and_receive__equal_the_plain_formulas_step_after_step() -> None:
    for layout, radius in (("tiny", 1), ("wh20", 2), ("wh20", 3)):
        env = EnvConfig.make(n_robots=12, layout=layout, horizon=40, loss_p=0.4)
        batch = EpisodeBatch(env, 3, batch_rng(0, 0, 0), None)
        board = AllToAllBoard(batch.core, LossProcess.from_config((3, 12, 12), env, batch.rng), radius)
        twin = AllToAllBoard(batch.core, LossProcess.from_config((3, 12, 12), env, batch_rng(0, 0, 0)), radius)
        twin.loss = board.loss = None  # both boards receive the same deliveries below
        rng = np.random.default_rng(radius)
        seen = 0.0
        for _ in range(25):
            delivered = rng.random((3, 12, 12)) < 0.6
            for brd in (board, twin):
                brd.loss = type("Fixed", (), {"step": staticmethod(lambda d=delivered: d.copy())})()
            board.receive()
            pos, ctl = twin.messages()  # the plain receive of the same step
            got = (delivered | twin.eye[None]).transpose(0, 2, 1)
            twin.pos = np.where(got, pos[:, None, :], twin.pos)
            twin.ctl = np.where(got, ctl[:, None, :], twin.ctl)
            twin.age = np.where(got, 0, twin.age + 1)
            for name in ("pos", "ctl", "age"):
                np.testing.assert_array_equal(getattr(board, name), getattr(twin, name))
            got_maps = board.features()
            np.testing.assert_array_equal(got_maps, plain_features(twin))
            seen += got_maps.sum()
            batch.core.step(rng.integers(0, 5, size=(3, 12)))
            batch.core.done |= rng.random((3, 12)) < 0.03  # some leave the floor (OFF_FLOOR)
        assert seen > 0  # robots did appear in windows
