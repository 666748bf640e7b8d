"""Robot-level all-to-all messages over lossy links, as the decentralized baseline sees them.

Every robot j transmits M_t^j = (p_t^j, U_{t-1}^j) (eq:message with each robot its own
group: d_m = 2 position + 1 control scalars) to every other robot at every step; the
directed link j -> i delivers it with probability 1 - p (the environment's robot-level
``Channel`` over (B, N, N) links ``[b, sender, receiver]``). Each receiver keeps the **last received** message of
every sender; at reset every robot knows every start position (the task assignment is
broadcast before the episode) with control Wait, so with p = 1 a receiver only ever holds
those initial messages. A completed robot that leaves the floor (``on_goal="remove"``)
keeps transmitting with the control code ``OFF_FLOOR``; receivers drop it from their map
once that message arrives. Payload: N (N - 1) d_m scalars per step, every step. With a
delayed channel (``EnvConfig.delay``) a receiver holds the freshest message that has
arrived on each link, and ``age`` is the time since it was sent (transit included).

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
from envs.channel import Channel, LossProcess
from envs.core import WarehouseCore

OFF_FLOOR = 5  # control code of a robot that completed and left the floor
AGE_CAP = 10.0
MAP_CHANNELS = 3


class AllToAllBoard:
    """Last received messages of B episodes: ``pos``, ``ctl``, ``age`` shaped (B, N_recv, N_send).

    Stored narrow (``pos`` int16 when the layout has < 2^15 free cells, else int32;
    ``ctl`` int8; ``age`` int32) and updated in place by integer
    blends, so a step touches (B, N, N) arrays a few bytes per entry; the values are those
    of the plain formulas (tests/algorithms/common/test_all_to_all_fast.py).
    """

    def __init__(self, core: WarehouseCore, loss: Channel | LossProcess, radius: int) -> None:
        b, n = core.pos.shape
        self.core, self.loss, self.radius = core, loss, radius
        self.n = n
        pos, _ = self.messages()
        small = core.layout.n_free <= np.iinfo(np.int16).max
        self.pos = np.broadcast_to(pos[:, None, :], (b, n, n)).astype(np.int16 if small else np.int32)  # cells
        self.ctl = np.full((b, n, n), WAIT, dtype=np.int8)  # (B, N, N) controls
        self.age = np.zeros((b, n, n), dtype=np.int32)  # (B, N, N) steps since received
        self._tmp: dict[type[np.generic], np.ndarray] = {  # scratch
            dt: np.empty((b, n, n), dtype=dt) for dt in (np.int8, np.int16, np.int32)}
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
        self._span = span = (h + 2 * radius) * wp  # padded indices lie in [0, span)
        dr, dc = np.divmod(np.arange(-span + 1, span) + radius * wp + radius, wp)
        inside = (dr >= 0) & (dr < self.side) & (dc < self.side)
        self._window = np.where(inside, dr * self.side + dc, -1).astype(np.int64)  # by offset + span - 1
        # ``features`` looks both channels up from one key pos * 6 + ctl per message: the
        # padded index of the received position (channel 0) and of the cell its control
        # leads to (channel 1), or OFF (outside every window: ctl OFF_FLOOR, or the robot
        # itself) for which ``_window_ext`` (the window table padded with -1) gives -1.
        self._off = off = 2 * span
        nxt = core.layout.next_cell  # (F, 5)
        here = np.repeat(self._center[:, None], OFF_FLOOR + 1, axis=1)
        ahead = np.concatenate([self._center[nxt], self._center[:, None]], axis=1)
        here[:, OFF_FLOOR] = ahead[:, OFF_FLOOR] = off
        self._key_center = np.stack([here.reshape(-1), ahead.reshape(-1)], axis=1).astype(np.int32)  # (F*6, 2)
        self._window_ext = np.full(3 * span, -1, dtype=np.int16 if self.side ** 2 < 2 ** 15 else np.int32)
        self._window_ext[: 2 * span - 1] = self._window
        # A delayed channel: the messages of the last ``slots`` steps, by send step mod slots.
        self._delay = loss.delay if isinstance(loss, Channel) else None
        if self._delay is not None:
            slots = self._delay.slots
            self._sent_pos = np.zeros((slots, b, n), dtype=self.pos.dtype)
            self._sent_ctl = np.zeros((slots, b, n), dtype=np.int8)

    def messages(self) -> tuple[np.ndarray, np.ndarray]:
        """This step's true messages: (B, N) cells and (B, N) controls U_{t-1} (or OFF_FLOOR)."""
        core = self.core
        ctl = core.prev_actions.copy()
        if core.remove:
            ctl[core.done] = OFF_FLOOR
        return core.pos, ctl

    def receive(self) -> np.ndarray:
        """Transmit this step's messages; returns the (B, N_send, N_recv) delivery mask A_t."""
        if self._delay is not None:
            return self._receive_delayed()
        pos, ctl = self.messages()
        delivered = self.loss.step() | self.eye[None]  # a robot always knows its own state
        got = np.ascontiguousarray(delivered.transpose(0, 2, 1))  # (B, N_recv, N_send)
        # In place, as integer blends x += (new - x) * got (exact): no (B, N, N) rebuilt, and
        # the factor got in the array's own dtype (a bool factor takes a slow casting loop).
        for arr, new in ((self.pos, pos), (self.ctl, ctl)):
            tmp = self._tmp[arr.dtype.type]
            np.subtract(new.astype(arr.dtype)[:, None, :], arr, out=tmp)
            arr += np.multiply(tmp, got.astype(arr.dtype), out=tmp)
        self.age += 1
        self.age *= np.logical_not(got).astype(np.int32)
        return delivered

    def _receive_delayed(self) -> np.ndarray:
        """``receive`` over a delayed channel: each receiver takes the freshest message
        that arrived on each link (sent ``age`` steps ago, d steps in transit) from the
        log of what was sent; returns where one arrived (the diagonal always)."""
        line, loss = self._delay, self.loss
        assert line is not None and isinstance(loss, Channel)
        t, slots = line.t, line.slots
        pos, ctl = self.messages()
        self._sent_pos[t % slots] = pos
        self._sent_ctl[t % slots] = ctl.astype(np.int8)
        loss.step()
        got = loss.arrived.transpose(0, 2, 1)  # (B, N_recv, N_send)
        sent = line.sent_at.transpose(0, 2, 1)
        b, n = pos.shape
        when = np.where(got, sent, t) % slots
        rows = np.arange(b)[:, None, None]
        senders = np.arange(n)[None, None, :]
        np.copyto(self.pos, self._sent_pos[when, rows, senders], where=got)
        np.copyto(self.ctl, self._sent_ctl[when, rows, senders], where=got)
        self.age[...] = t - sent  # t + 1 for the start broadcast (sent_at -1)
        own = self.eye[None]  # a robot always knows its own state
        np.copyto(self.pos, pos[:, None, :].astype(self.pos.dtype), where=own)
        np.copyto(self.ctl, ctl[:, None, :].astype(np.int8), where=own)
        self.age[:, self.eye] = 0
        return loss.arrived | own

    @property
    def payload(self) -> int:
        """Scalars transmitted per step: N (N - 1) d_m (every directed link, lost or not)."""
        return self.n * (self.n - 1) * self.core.config.d_m

    def features(self, out: np.ndarray | None = None) -> np.ndarray:
        """(B, N, 3 (2k+1)^2) float32 egocentric maps of the received messages (see module);
        written into ``out`` when given (any (B, N, 3 (2k+1)^2) float32 view)."""
        core, side = self.core, self.side
        b, n = core.pos.shape
        p = side * side
        if out is None:
            out = np.empty((b, n, MAP_CHANNELS * p), dtype=np.float32)
        key = self._tmp[np.int32]
        np.multiply(self.pos, OFF_FLOOR + 1, out=key, dtype=np.int32)
        key += self.ctl
        me = (self._center[core.pos] - (self._span - 1)).astype(np.int32)[:, :, None, None]
        # Channels 0 and 1 in one pass (np.take: several times faster than fancy indexing).
        where = np.take(self._key_center, key, axis=0)  # (B, N, N, 2) padded index, or OFF
        where.reshape(b, n * n, 2)[:, :: n + 1] = self._off  # not the robot itself
        where -= me
        cell = np.take(self._window_ext, where).reshape(-1)  # window cell or -1
        hit = np.flatnonzero(cell >= 0)  # (receiver, sender, channel) in C order
        ch = hit & 1
        pair = hit >> 1  # receiver-sender pair b N N + i N + j
        flat = ((pair // n) * MAP_CHANNELS + ch) * p + cell[hit]  # into (B, N, 3, P)
        here = ch == 0
        stale = np.minimum(self.age.reshape(-1)[pair[here]], AGE_CAP).astype(np.float32) * (1.0 / AGE_CAP)
        # One bincount: counts of channels 0 and 1 (weight 1, exact), then channel 2's
        # staleness at the channel-0 hits, summed per cell in the same (C) order as before.
        sums = np.bincount(np.concatenate([flat, flat[here] + 2 * p]),
                           weights=np.concatenate([np.ones(flat.size), stale]),
                           minlength=b * n * MAP_CHANNELS * p)
        out[...] = sums.reshape(b, n, MAP_CHANNELS * p)
        return out


def map_feature_size(radius: int) -> int:
    return MAP_CHANNELS * (2 * radius + 1) ** 2
