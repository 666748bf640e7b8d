"""Robot-level observations of the baselines: a robot's own state and its local view.

Every learned method observes, per robot, ``envs.observations.robot_features``:

    [position/shape (2), goal offset/shape (2), distance/(H+W) (1), done (1),
     action_progress (5), shelf patch (2k+1)^2, robot patch (2k+1)^2]

The robot patch is the robot's own sensing of the cells around it: the current cells of
the robots on the floor in its (2k+1)^2 window (ground truth, no channel; IC3Net's
reference environments likewise give agents vision of nearby agents). It is built in one
place, ``PatchExtractor`` (vectorized over B and N). The baselines (``local_view``) see
every nearby robot; the hierarchical local policy sees only its own group's robots
(``robot_features(core, patch, groups)``), because pi_theta_z may depend on X^z, G^z and
r only (Sec. III-B, Proposition 1); other groups reach it through the reference.
``action_mask`` is the environment's action mask (moves into shelves or off the grid are
disallowed).
"""
from __future__ import annotations

import numpy as np

from envs.actions import DELTAS, N_ACTIONS
from envs.core import WarehouseCore
from envs.observations import (
    STATE_SIZE,
    PatchExtractor,
    feature_size,
    robot_features,
    state_features_into,
)


def local_view(core: WarehouseCore, patch: PatchExtractor) -> np.ndarray:
    """(B, N, local_view_size(k)) float32: a robot's own state, the shelves and the
    robots (any group) in its (2k+1)^2 window."""
    return robot_features(core, patch)


def local_view_into(core: WarehouseCore, patch: PatchExtractor, out: np.ndarray) -> None:
    """``local_view`` written into ``out`` (a (B, N, local_view_size(k)) float32 view, e.g.
    a row of a rollout buffer): the three writes of ``robot_features``, without its
    (B, N, F) allocation and the caller's copy (same numbers; tests/algorithms/common/test_robot_obs.py)."""
    p = patch.offsets.size
    state_features_into(core, out[..., :STATE_SIZE])
    np.take(patch.shelf_table(), core.pos, axis=0, out=out[..., STATE_SIZE:STATE_SIZE + p], mode="clip")
    patch.robots_into(out[..., STATE_SIZE + p:STATE_SIZE + 2 * p])


def local_view_size(radius: int) -> int:
    return feature_size(radius)


def robots_on_target_index(radius: int) -> np.ndarray:
    """(1, 5) columns of ``local_view`` (and ``robot_features``) holding, for each action,
    the robot patch at the cell that action leads to (0 for Wait: the robot itself)."""
    side = 2 * radius + 1
    robots = 11 + side * side  # start of the robot channel of the patch
    return np.array([[robots + (radius + dr) * side + (radius + dc) for dr, dc in DELTAS.tolist()]])


def own_history(core: WarehouseCore, collided: np.ndarray) -> np.ndarray:
    """(B, N, 6) float32: one-hot of the robot's own previous control U_{t-1} (the control
    it also transmits, eq:message) and whether it was stopped by a conflict last step
    (``collided`` (B, N) bool, what a robot senses when its move did not happen)."""
    onehot = np.eye(N_ACTIONS, dtype=np.float32)[core.prev_actions]
    return np.concatenate([onehot, collided[..., None].astype(np.float32)], axis=-1)


HISTORY_SIZE = N_ACTIONS + 1
_ONEHOT = np.eye(N_ACTIONS, dtype=np.float32)


def own_history_into(core: WarehouseCore, collided: np.ndarray, out: np.ndarray) -> None:
    """``own_history`` written into ``out`` (a (B, N, 6) float32 view)."""
    np.take(_ONEHOT, core.prev_actions, axis=0, out=out[..., :N_ACTIONS], mode="clip")
    out[..., N_ACTIONS] = collided


def action_mask_into(core: WarehouseCore, out: np.ndarray) -> None:
    """``action_mask`` written into ``out`` (a (B, N, 5) bool view)."""
    np.take(core.layout.move_valid, core.pos, axis=0, out=out, mode="clip")


def action_mask(core: WarehouseCore) -> np.ndarray:
    """(B, N, 5) bool: actions that do not run into a shelf or off the grid (Wait always)."""
    return core.layout.move_valid[core.pos]
