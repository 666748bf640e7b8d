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
        self.others = ~self.eye[None]  # (1, N, N) no self-messages in the maps
        self.side = 2 * radius + 1
        # Window lookup: cells as indices of the grid padded by k on every side, so the
        # difference of two padded indices identifies the window cell (or none) uniquely
        # (a column offset beyond k cannot alias into the window: |dc| <= W - 1 < W' - k).
        h, w = core.layout.shape
        wp = w + 2 * radius
        cells = core.layout.cells
        self._center = ((cells[:, 0] + radius) * wp + cells[:, 1] + radius).astype(np.int64)  # (F,)
        self._span = (h + 2 * radius) * wp  # padded indices lie in [0, span)
        dr, dc = np.divmod(np.arange(-self._span + 1, self._span) + radius * wp + radius, wp)
        inside = (dr >= 0) & (dr < self.side) & (dc < self.side)
        self._window = np.where(inside, dr * self.side + dc, -1).astype(np.int64)  # by offset + span - 1

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
        got = np.ascontiguousarray(delivered.transpose(0, 2, 1))  # (B, N_recv, N_send)
        np.copyto(self.pos, pos[:, None, :], where=got)  # in place: no (B, N, N) rebuilt per step
        np.copyto(self.ctl, ctl[:, None, :], where=got)
        self.age += 1
        np.copyto(self.age, 0, where=got)
        return delivered

    @property
    def payload(self) -> int:
        """Scalars transmitted per step: N (N - 1) d_m (every directed link, lost or not)."""
        return self.n * (self.n - 1) * self.core.config.d_m

    def features(self) -> np.ndarray:
        """(B, N, 3 (2k+1)^2) float32 egocentric maps of the received messages (see module)."""
        core, side = self.core, self.side
        b, n = core.pos.shape
        valid = self.ctl != OFF_FLOOR
        valid &= self.others  # (B, N, N)
        projected = core.layout.next_cell[self.pos, np.minimum(self.ctl, WAIT)]  # (B, N, N)
        me = (self._center[core.pos] - (self._span - 1))[:, :, None]  # (B, N, 1)
        base = np.arange(b * n, dtype=np.int64).reshape(b, n, 1) * (side * side)
        size = b * n * side * side
        out = np.empty((b, n, MAP_CHANNELS, side * side), dtype=np.float32)
        for ch, where in ((0, self.pos), (1, projected)):
            cell = self._window[self._center[where] - me]  # (B, N, N) window cell or -1
            inside = cell >= 0
            inside &= valid
            flat = (base + cell)[inside]
            out[:, :, ch] = np.bincount(flat, minlength=size).reshape(b, n, -1)
            if ch == 0:
                stale = np.minimum(self.age[inside], AGE_CAP).astype(np.float32) * (1.0 / AGE_CAP)
                out[:, :, 2] = np.bincount(flat, weights=stale, minlength=size).reshape(b, n, -1)
        return out.reshape(b, n, -1)


def map_feature_size(radius: int) -> int:
    return MAP_CHANNELS * (2 * radius + 1) ** 2
