"""Robot-level observations of the baselines: a robot's own state over the static map.

Both learned baselines (decentralized, IC3Net) give each robot the parts of
``envs.observations.robot_features`` that a single robot knows by itself:

    [position/shape (2), goal offset/shape (2), distance/(H+W) (1), done (1),
     action_progress (5), shelf patch (2k+1)^2]

and nothing about other robots: what a robot knows of the others arrives over the lossy
channel (the decentralized baseline's messages, IC3Net's communication vectors), as for
the hierarchical method, whose patch shows only same-group robots (SPEC 3). With each
robot its own group, that same-group robot channel is empty, so it is left out here
(the decentralized baseline puts its message map in its place). ``action_mask`` is the
environment's action mask (moves into shelves or off the grid are disallowed).
"""
from __future__ import annotations

import numpy as np

from envs.actions import N_ACTIONS
from envs.core import WarehouseCore
from envs.observations import PatchExtractor, state_features


def own_features(core: WarehouseCore, patch: PatchExtractor) -> np.ndarray:
    """(B, N, own_feature_size(k)) float32: a robot's own state and the shelves around it."""
    shelves = patch.pad_obs[patch.center[core.pos][..., None] + patch.offsets]  # (B, N, P)
    return np.concatenate([state_features(core), shelves], axis=-1)


def own_feature_size(radius: int) -> int:
    return 2 + 2 + 1 + 1 + N_ACTIONS + (2 * radius + 1) ** 2


def own_history(core: WarehouseCore, collided: np.ndarray) -> np.ndarray:
    """(B, N, 6) float32: one-hot of the robot's own previous control U_{t-1} (the control
    it also transmits, eq:message) and whether it was stopped by a conflict last step
    (``collided`` (B, N) bool, what a robot senses when its move did not happen)."""
    onehot = np.eye(N_ACTIONS, dtype=np.float32)[core.prev_actions]
    return np.concatenate([onehot, collided[..., None].astype(np.float32)], axis=-1)


HISTORY_SIZE = N_ACTIONS + 1


def action_mask(core: WarehouseCore) -> np.ndarray:
    """(B, N, 5) bool: actions that do not run into a shelf or off the grid (Wait always)."""
    return core.layout.move_valid[core.pos]
