"""Groups, links and the inter-group messages M_t^{z',z} = (X_t^{z'}, U_{t-1}^{z'}) (eq:message).

Groups have different sizes (robot i in group i mod Z), so per-group arrays are padded to
the largest group, n = max_z |N_z|, with a slot mask. Directed links are stored per
receiver: ``neighbors[z, k]`` is the k-th communication neighbour z' in C^z (padded with
-1 for graphs whose in-degrees differ).

A message holds one row per robot slot of the sender, ``MSG_DIM`` numbers:
[row, col (grid cells), one-hot U_{t-1} (5), present]. ``present`` is 0 for a robot that
has left the floor (completed with ``on_goal="remove"``) and for padding; such rows are
all zeros otherwise, so an absent robot is a sentinel row, never a stale position.
The channel itself transmits d_m = 3 scalars per robot (SPEC 2); the one-hot is only the
encoding the predictor is trained on (eq:gru_pred_loss).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envs.actions import N_ACTIONS
from envs.channel import comm_graph, group_assignment, group_members
from envs.config import EnvConfig
from envs.core import WarehouseCore
from envs.layouts import Layout

MSG_DIM = 2 + N_ACTIONS + 1
POS, CTRL, PRESENT = slice(0, 2), slice(2, 2 + N_ACTIONS), 2 + N_ACTIONS


@dataclass(frozen=True)
class GroupStructure:
    """Fixed groups (Assumption 1) and the directed group graph G."""

    groups: np.ndarray  # (N,) group of each robot
    members: np.ndarray  # (Z, n) robot index per slot, -1 for padding
    slot_valid: np.ndarray  # (Z, n) bool
    neighbors: np.ndarray  # (Z, K) sender z' per receiver z, -1 for padding
    link_valid: np.ndarray  # (Z, K) bool

    @property
    def n_groups(self) -> int:
        return int(self.members.shape[0])

    @property
    def n_slots(self) -> int:
        return int(self.members.shape[1])

    def gather(self, per_robot: np.ndarray, fill: object = 0) -> np.ndarray:
        """(B, N, ...) -> (B, Z, n, ...) grouped by slot; padding slots hold ``fill``."""
        out = per_robot[:, np.maximum(self.members, 0)]
        if not self.slot_valid.all():
            pad = ~self.slot_valid
            out[:, pad] = fill
        return out

    def scatter(self, per_slot: np.ndarray, n_robots: int) -> np.ndarray:
        """(B, Z, n, ...) -> (B, N, ...), the inverse of ``gather`` on valid slots."""
        out = np.empty((per_slot.shape[0], n_robots) + per_slot.shape[3:], dtype=per_slot.dtype)
        out[:, self.members[self.slot_valid]] = per_slot[:, self.slot_valid]
        return out

    def links(self, per_group: np.ndarray) -> np.ndarray:
        """(B, Z, ...) sender data -> (B, Z, K, ...) as received on each link [b, z, k]."""
        return per_group[:, np.maximum(self.neighbors, 0)]

    def link_availability(self, avail: np.ndarray) -> np.ndarray:
        """(B, Z', Z) channel availability [b, z', z] -> (B, Z, K) per receiver and link."""
        z = np.arange(self.n_groups)[:, None]
        return avail[:, np.maximum(self.neighbors, 0), z] & self.link_valid[None]


def group_structure(config: EnvConfig) -> GroupStructure:
    n, z = config.n_robots, config.groups
    members = group_members(n, z)
    adj = comm_graph(z, config.comm_graph)  # [z', z]
    k = max(int(adj.sum(axis=0).max()), 1)
    neighbors = np.full((z, k), -1, dtype=np.int64)
    for zz in range(z):
        senders = np.flatnonzero(adj[:, zz])
        neighbors[zz, : len(senders)] = senders
    return GroupStructure(
        groups=group_assignment(n, z), members=members, slot_valid=members >= 0,
        neighbors=neighbors, link_valid=neighbors >= 0,
    )


def message_vectors(layout: Layout, pos: np.ndarray, prev: np.ndarray, present: np.ndarray) -> np.ndarray:
    """(...) cell index, previous control, present flag -> (..., MSG_DIM) float32 rows."""
    out = np.zeros(pos.shape + (MSG_DIM,), dtype=np.float32)
    rc = layout.cells[np.maximum(pos, 0)].astype(np.float32)
    pres = present.astype(np.float32)
    out[..., POS] = rc * pres[..., None]
    out[..., CTRL] = np.eye(N_ACTIONS, dtype=np.float32)[prev] * pres[..., None]
    out[..., PRESENT] = pres
    return out


def group_messages(core: WarehouseCore, gs: GroupStructure) -> np.ndarray:
    """(B, Z, n, MSG_DIM): the message M_t^{z'} each group z' sends at the current step."""
    present = gs.gather(core.occupying, fill=False)
    pos = gs.gather(core.pos, fill=0)
    prev = gs.gather(core.prev_actions, fill=0)
    return message_vectors(core.layout, pos, prev, present)
