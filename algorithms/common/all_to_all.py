"""Robot-level all-to-all messages over lossy links, as the decentralized baseline sees them.

Every robot j transmits M_t^j = (p_t^j, U_{t-1}^j) (eq:message with each robot its own
group: d_m = 2 position + 1 control scalars) to every other robot at every step; the
directed link j -> i delivers it with probability 1 - p (``LossProcess`` over (B, N, N)
links ``[b, sender, receiver]``). Each receiver keeps the **last received** message of
every sender; at reset every robot knows every start position (the task assignment is
broadcast before the episode) with control Wait, so with p = 1 a receiver only ever holds
those initial messages. A completed robot that leaves the floor (``on_goal="remove"``)
keeps transmitting with the control code ``OFF_FLOOR``; receivers drop it from their map
once that message arrives. Payload: N (N - 1) d_m scalars per step, every step.

``features`` turns a receiver's view into a permutation-invariant encoding that works for
any N: egocentric maps of the same window as the shelf patch (sum-pooling of one-hot
relative positions), with channels

    0: robots at their received positions,
    1: robots at the cell their received control leads to (received position moved once),
    2: staleness of those messages, min(age, AGE_CAP) / AGE_CAP summed per cell.
"""
from __future__ import annotations

import numpy as np

from envs.actions import WAIT
from envs.channel import LossProcess
from envs.core import WarehouseCore

OFF_FLOOR = 5  # control code of a robot that completed and left the floor
AGE_CAP = 10.0
MAP_CHANNELS = 3


class AllToAllBoard:
    """Last received messages of B episodes: ``pos``, ``ctl``, ``age`` shaped (B, N_recv, N_send)."""

    def __init__(self, core: WarehouseCore, loss: LossProcess, radius: int) -> None:
        b, n = core.pos.shape
        self.core, self.loss, self.radius = core, loss, radius
        self.n = n
        pos, _ = self.messages()
        self.pos = np.broadcast_to(pos[:, None, :], (b, n, n)).copy()  # (B, N, N) cells
        self.ctl = np.full((b, n, n), WAIT, dtype=np.int64)  # (B, N, N) controls
        self.age = np.zeros((b, n, n), dtype=np.int64)  # (B, N, N) steps since received
        self.eye = np.eye(n, dtype=bool)
        self.side = 2 * radius + 1

    def messages(self) -> tuple[np.ndarray, np.ndarray]:
        """This step's true messages: (B, N) cells and (B, N) controls U_{t-1} (or OFF_FLOOR)."""
        core = self.core
        ctl = core.prev_actions.copy()
        if core.remove:
            ctl[core.done] = OFF_FLOOR
        return core.pos, ctl

    def receive(self) -> np.ndarray:
        """Transmit this step's messages; returns the (B, N_send, N_recv) delivery mask A_t."""
        pos, ctl = self.messages()
        delivered = self.loss.step() | self.eye[None]  # a robot always knows its own state
        got = delivered.transpose(0, 2, 1)  # (B, N_recv, N_send)
        self.pos = np.where(got, pos[:, None, :], self.pos)
        self.ctl = np.where(got, ctl[:, None, :], self.ctl)
        self.age = np.where(got, 0, self.age + 1)
        return delivered

    @property
    def payload(self) -> int:
        """Scalars transmitted per step: N (N - 1) d_m (every directed link, lost or not)."""
        return self.n * (self.n - 1) * self.core.config.d_m

    def features(self) -> np.ndarray:
        """(B, N, 3 (2k+1)^2) float32 egocentric maps of the received messages (see module)."""
        core, k, side = self.core, self.radius, self.side
        b, n = core.pos.shape
        cells = core.layout.cells
        me = cells[core.pos][:, :, None, :]  # (B, N, 1, 2)
        valid = (self.ctl != OFF_FLOOR) & ~self.eye[None]  # (B, N, N)
        ctl = np.minimum(self.ctl, WAIT)
        projected = core.layout.next_cell[self.pos, ctl]  # (B, N, N)
        stale = np.minimum(self.age, AGE_CAP).astype(np.float64) / AGE_CAP
        base = np.arange(b * n, dtype=np.int64).reshape(b, n, 1) * (side * side)
        size = b * n * side * side
        out = np.empty((b, n, MAP_CHANNELS, side * side), dtype=np.float32)
        for ch, (where, weights) in enumerate(((self.pos, None), (projected, None), (self.pos, stale))):
            rel = cells[where] - me + k  # (B, N, N, 2)
            inside = valid & (rel >= 0).all(axis=-1) & (rel < side).all(axis=-1)
            flat = base + rel[..., 0] * side + rel[..., 1]
            w = None if weights is None else weights[inside]
            out[:, :, ch] = np.bincount(flat[inside], weights=w, minlength=size).reshape(b, n, -1)
        return out.reshape(b, n, -1)


def map_feature_size(radius: int) -> int:
    return MAP_CHANNELS * (2 * radius + 1) ** 2
