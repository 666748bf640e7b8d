"""The recurrent interaction-state predictor f_eta_z (eq:predictor_input..eq:interaction_state_collection).

Every receiver group z keeps, for each neighbour z' in C^z, a predictor state made of
* a GRU hidden vector h_t^{z',z} (one per link, eq:recurrent_predictor), and
* the last message received on the link with its age (steps since it was sent).

Each step the GRU reads the null-or-message input M-bar (eq:predictor_input: the true
message when A=1, zeros of message size when A=0), the availability flag A, the age and an
encoding of the receiver's own state X^z. Messages and X^z enter through a per-robot
embedding pooled over present robots (any group size; a null input pools to zeros). The
decoder predicts, for every robot slot of z', a message row from the hidden state, the
last received row, its age and the dead-reckoning displacement (age x the move of the last
received control): position = last position + predicted displacement (cells), previous
control as probabilities, present as a probability. The completed message M-hat is the
received one when A=1 and the prediction otherwise (eq:interaction_state_estimate).

Training is supervised by the true messages on lost steps only (eq:gru_pred_loss),
separately from the policy gradient. Predicted positions are snapped to the nearest free
cell (``SnapToFree``) before the reference encoder and the safety filter use them.
Parameters are per receiver group (eta_z) or shared, see ``group_layers``.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import torch
from scipy import ndimage
from torch import nn

from algorithms.hierarchical.group_layers import GroupGRUCell, GroupMLP, masked_mean
from algorithms.hierarchical.messages import CTRL, MSG_DIM, POS, PRESENT
from envs.actions import DELTAS
from envs.layouts import Layout

AGE_SCALE = 8.0  # age feature = min(age, 4 * AGE_SCALE) / AGE_SCALE


class GroupPredictor(nn.Module):
    """f_eta_z for all receiver groups at once; tensors are group-major (Z, M, K, ...)."""

    scale: torch.Tensor  # buffer (2,): the grid's (H, W), positions to [0, 1]
    msg_scale: torch.Tensor  # (MSG_DIM,): (H, W, 1, ..., 1), the divisor of ``_norm``
    deltas: torch.Tensor  # buffer (5, 2): each action's (row, col) step

    def __init__(self, n_param_groups: int, n_groups: int, grid_shape: tuple[int, int],
                 hidden: int = 64, embed: int = 32) -> None:
        super().__init__()
        self.hidden = hidden
        self.register_buffer("scale", torch.tensor([float(grid_shape[0]), float(grid_shape[1])]))
        # Not a buffer (checkpoints keep their keys): the divisor of ``_norm``.
        self.msg_scale = torch.cat([self.scale, torch.ones(MSG_DIM - 2)])
        p, z = n_param_groups, n_groups
        self.msg_embed = GroupMLP(p, z, [MSG_DIM, embed], final_activation=True)
        self.own_embed = GroupMLP(p, z, [MSG_DIM, embed], final_activation=True)
        self.gru = GroupGRUCell(p, z, 2 * embed + 2, hidden)
        self.decoder = GroupMLP(p, z, [hidden + MSG_DIM + 3, embed, MSG_DIM])
        self.register_buffer("deltas", torch.from_numpy(DELTAS.astype(np.float32)))

    def _apply(self, fn: Callable[[torch.Tensor], torch.Tensor], recurse: bool = True) -> GroupPredictor:
        """``Module._apply`` (``.to(device)``, ...), with ``msg_scale`` (no buffer) moved alike."""
        super()._apply(fn, recurse)
        self.msg_scale = fn(self.msg_scale)
        return self

    def _norm(self, msg: torch.Tensor) -> torch.Tensor:
        """Positions to [0, 1], the rest unchanged: one division by (H, W, 1, ..., 1)
        (x / 1 is x exactly in IEEE arithmetic, so the same values as dividing the
        positions alone and concatenating; tests/algorithms/hierarchical/test_hot_paths.py)."""
        return msg / self.msg_scale

    @staticmethod
    def age_feature(age: torch.Tensor) -> torch.Tensor:
        return age.to(torch.float32).clamp_max(4 * AGE_SCALE) / AGE_SCALE

    def encode(self, msg_bar: torch.Tensor, avail: torch.Tensor, age: torch.Tensor,
               own: torch.Tensor) -> torch.Tensor:
        """GRU input (Z, M, K, 2E+2) from M-bar (Z, M, K, n, D), A (Z, M, K), age (Z, M, K)
        and the receiver's own message rows X^z (Z, M, n, D)."""
        e = masked_mean(self.msg_embed(self._norm(msg_bar)), msg_bar[..., PRESENT] > 0, dim=-2)
        o = masked_mean(self.own_embed(self._norm(own)), own[..., PRESENT] > 0, dim=-2)
        o = o.unsqueeze(2).expand(-1, -1, e.shape[2], -1)
        a = avail.to(torch.float32).unsqueeze(-1)
        return torch.cat([e, o, a, self.age_feature(age).unsqueeze(-1)], dim=-1)

    def step(self, x: torch.Tensor, h: torch.Tensor) -> torch.Tensor:
        """eq:recurrent_predictor: h_t = GRU(h_{t-1}, x_t); (Z, M, K, .) tensors."""
        return self.gru(x, h)

    def input_gates(self, x: torch.Tensor) -> torch.Tensor:
        """The GRU's input half for many steps at once: x (Z, ..., 2E+2) -> (Z, ..., 3H);
        ``step_from_gates(input_gates(x_t), h)`` equals ``step(x_t, h)`` up to float
        rounding of the larger matmul."""
        return self.gru.ih(x)

    def step_from_gates(self, gi: torch.Tensor, h: torch.Tensor) -> torch.Tensor:
        return self.gru.from_input_gates(gi, h)

    def decode(self, h: torch.Tensor, mem: torch.Tensor, age: torch.Tensor) -> torch.Tensor:
        """Predicted messages M~ (..., n, D) in message units from h (..., H), the last
        received rows mem (..., n, D) and their age (...); the leading axis is the group."""
        n = mem.shape[-2]
        age_f = self.age_feature(age)[..., None, None].expand(*age.shape, n, 1)
        inp = torch.cat([
            h.unsqueeze(-2).expand(*h.shape[:-1], n, h.shape[-1]),
            self._norm(mem),
            age_f,
            age_f * (mem[..., CTRL] @ self.deltas),  # dead reckoning with the last control
        ], dim=-1)
        out = self.decoder(inp)
        pos = mem[..., POS] + out[..., POS]
        ctrl = torch.softmax(out[..., CTRL], dim=-1)
        pres = torch.sigmoid(out[..., PRESENT:])
        return torch.cat([pos, ctrl, pres], dim=-1)


def prediction_error(pred: torch.Tensor, target: torch.Tensor, slot_valid: torch.Tensor) -> torch.Tensor:
    """||M~ - M||^2 summed over the robot slots of each message (eq:gru_pred_loss).

    pred, target (..., n, D); slot_valid (..., n) bool (padding slots of the sender are
    ignored). Position and control errors count only for robots present in the true
    message (an absent robot has no position); the present flag always counts.
    """
    present = target[..., PRESENT]
    sq = (pred - target) ** 2
    per_robot = present * sq[..., :PRESENT].sum(-1) + sq[..., PRESENT]
    return (per_robot * slot_valid.to(per_robot.dtype)).sum(-1)


def predictor_loss(pred: torch.Tensor, target: torch.Tensor, lost: torch.Tensor,
                   slot_valid: torch.Tensor, n_group_steps: torch.Tensor | float) -> torch.Tensor:
    """L_c (eq:gru_pred_loss): sum over lost links (1 - A = 1) of the message error, averaged
    over the running group-steps (the empirical expectation). Delivered links contribute
    nothing whatever the prediction. pred, target (..., n, D); lost (...) bool."""
    err = prediction_error(pred, target, slot_valid)
    return (err * lost.to(err.dtype)).sum() / n_group_steps


@dataclass
class PredictorState:
    """Rollout state of every link of B episodes (the GRU hidden and the last received rows)."""

    h: torch.Tensor  # (Z, B, K, H)
    mem: np.ndarray  # (B, Z, K, n, D) last received message per link
    age: np.ndarray  # (B, Z, K) int64 steps since ``mem`` was sent (-1 before step 0)


def initial_state(model: GroupPredictor, link_msgs: np.ndarray) -> PredictorState:
    """Reset at an episode start: h = 0; the start configuration (part of the task
    assignment) is known to every coordinator, so the memory holds M_0, aged 0 at step 0
    whether or not M_0 itself arrives."""
    b, z, k = link_msgs.shape[:3]
    return PredictorState(torch.zeros(z, b, k, model.hidden, device=model.scale.device), link_msgs.copy(),
                          np.full((b, z, k), -1, dtype=np.int64))


def rollout_step(model: GroupPredictor, state: PredictorState, link_msgs: np.ndarray,
                 avail: np.ndarray, own_msgs: np.ndarray,
                 decoders: Sequence[tuple[GroupPredictor, int, int]] | None = None) -> np.ndarray:
    """One predictor step for B episodes (no grad); updates ``state`` in place.

    link_msgs (B, Z, K, n, D) true messages on each link, avail (B, Z, K) bool, own_msgs
    (B, Z, n, D) -> completed messages M-hat (B, Z, K, n, D) (eq:interaction_state_estimate).
    ``decoders``: for a seed-stacked batch (``algorithms/common/seed_stack.py``), each seed's
    own predictor with its episode rows (lo, hi), which decodes its lost links as its own
    run would; default: ``model`` decodes the whole batch.
    """
    state.age = np.where(avail, 0, state.age + 1)
    state.mem = np.where(avail[..., None, None], link_msgs, state.mem)
    msg_bar = link_msgs * avail[..., None, None]  # eq:predictor_input (null = zeros)
    def to_t(a: np.ndarray) -> torch.Tensor:
        return _group_major(a).to(model.scale.device)

    x = model.encode(to_t(msg_bar), to_t(avail), to_t(state.age), to_t(own_msgs))
    state.h = model.step(x, state.h)
    out = link_msgs.copy()
    for dec, lo, hi in decoders if decoders is not None else [(model, 0, avail.shape[0])]:
        _decode_lost(dec, state.h[:, lo:hi], state.mem[lo:hi], state.age[lo:hi], ~avail[lo:hi], out[lo:hi])
    return out


def _decode_lost(model: GroupPredictor, h_all: torch.Tensor, mem_all: np.ndarray, age_all: np.ndarray,
                 lost: np.ndarray, out: np.ndarray) -> None:
    """Write the predicted messages of the lost links into ``out`` (B, Z, K, n, D): only the
    lost links are decoded (the others keep the received message), padded per group."""
    if not lost.any():
        return
    b, z, k = lost.shape
    lost_z = lost.transpose(1, 0, 2).reshape(z, b * k)
    count = lost_z.sum(axis=1)
    sel = np.argsort(~lost_z, axis=1, kind="stable")[:, : int(count.max())]  # (Z, W)
    zi = np.arange(z)[:, None]
    mem = mem_all.transpose(1, 0, 2, 3, 4).reshape(z, b * k, *mem_all.shape[3:])[zi, sel]
    age = age_all.transpose(1, 0, 2).reshape(z, b * k)[zi, sel]
    h = h_all.reshape(z, b * k, -1)[torch.from_numpy(zi), torch.from_numpy(sel)]
    dev = model.scale.device
    pred = model.decode(h, torch.from_numpy(mem).to(dev), torch.from_numpy(age).to(dev)).cpu().numpy()
    valid = np.arange(sel.shape[1])[None, :] < count[:, None]
    zz = np.broadcast_to(zi, sel.shape)[valid]
    out[sel[valid] // k, zz, sel[valid] % k] = pred[valid]


def _group_major(a: np.ndarray) -> torch.Tensor:
    """(B, Z, ...) numpy -> (Z, B, ...) torch."""
    return torch.from_numpy(np.ascontiguousarray(np.swapaxes(a, 0, 1)))


class SnapToFree:
    """Rounds predicted (row, col) to the grid and moves it to the nearest free cell."""

    def __init__(self, layout: Layout) -> None:
        _, idx = ndimage.distance_transform_edt(layout.obstacles, return_indices=True)
        self.nearest = layout.cell_index[idx[0], idx[1]]  # (H, W) free-cell index
        self.shape = layout.shape

    def __call__(self, rc: np.ndarray) -> np.ndarray:
        """(..., 2) float (row, col) -> (...) int64 free-cell index."""
        r = np.clip(np.rint(rc[..., 0]), 0, self.shape[0] - 1).astype(np.int64)
        c = np.clip(np.rint(rc[..., 1]), 0, self.shape[1] - 1).astype(np.int64)
        return self.nearest[r, c]
