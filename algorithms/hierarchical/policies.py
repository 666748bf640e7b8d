"""Reference policy mu_psi_z and local policy pi_theta_z with their encoders (Sec. III-B, III-C).

Per-robot inputs come from ``envs.observations`` (one definition for every method):
normalized position, goal offset, distance, done flag, per-action shortest-path progress
and a local patch of shelves and same-group robots (``robot_features`` with the group
mask). These depend on X^z and G^z (and the static map) only.

* Enc_r + mu (eq:reference_policy): each robot's features plus ``neighbor_patches``, a
  patch of the completed inter-group information S-hat^z (neighbour robots at their
  received-or-predicted cells, and the cells their last controls lead to), embedded per
  robot, mean-pooled over the group's robots -> o_t^z -> logits over |R_z| references.
* Enc_u + pi (eq:local_policy): each robot's features embedded, a group encoding
  mean-pooled over the group's robots, and the reference embedding -> per-robot logits;
  the joint control is a product of these per-robot categoricals. ``LocalPolicy.forward``
  takes no S-hat argument: inter-group information reaches it only through r
  (Proposition 1), by construction.

Both pool over sets with masks, so any group size uses the same weights. All tensors are
group-major (Z, M, n, ...), M = batch rows (``group_major``); weights are per group (see
``group_layers``). ``policy_forward`` runs both levels from per-robot rows, for the
rollout (``method.py``) and the update (``training.py``) alike.
Shelf moves are masked in pi (they are invalid and never admissible; docs/decisions/0108).
"""
from __future__ import annotations

from typing import cast

import numpy as np
import torch
from torch import nn

from algorithms.common.action_path import ACTION_GAIN, progress_index  # shared with the baselines
from algorithms.common.execution import ActionChoice
from algorithms.common.robot_obs import robots_on_target_index
from algorithms.hierarchical.group_layers import GroupLinear, GroupMLP, masked_mean, per_slice, relu
from algorithms.hierarchical.messages import GroupStructure
from envs.actions import N_ACTIONS
from envs.observations import PatchExtractor


def neighbor_patch_size(radius: int) -> int:
    return 2 * (2 * radius + 1) ** 2


def neighbor_patches(patch: PatchExtractor, gs: GroupStructure, cells: np.ndarray,
                     present: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """(B, N, 2 (2k+1)^2) uint8 windows of S-hat around every robot, seen by its group.

    cells, present, heading: (B, Z, K, n) neighbour robots as group z sees them on each
    link k: received-or-predicted cell, present flag, and the cell their last control
    leads to. Channel 0 counts neighbour robots, channel 1 their headings.
    """
    b, z = cells.shape[:2]
    size = patch.pad_obs.size
    plane = b * z * size  # one padded grid per (episode, receiving group) and channel
    rows = ((np.arange(b)[:, None] * z + np.arange(z)[None, :]) * size)[:, :, None, None]  # (B, Z, 1, 1)
    flat = np.concatenate([(rows + patch.center[cells])[present],
                           (rows + patch.center[heading])[present] + plane])
    # Counts saturate at 255 in the grid itself (uint8), so the gather yields the windows
    # without a pass to clip and convert them: the same values as clipping afterwards.
    grid = patch.scratch("neighbors_u8", 2 * plane, np.uint8)  # zeros, kept across steps
    cells_hit, counts = np.unique(flat, return_counts=True)
    grid[cells_hit] = np.minimum(counts, 255)
    core = patch.core
    row = (np.arange(b)[:, None] * z + gs.groups[None, :]) * size  # (B, N)
    windows = np.concatenate([patch.offsets, patch.offsets + plane])  # both channels, (2P,)
    out = grid.take((row + patch.center[core.pos])[..., None] + windows)  # (B, N, 2P) uint8
    grid[cells_hit] = 0
    return out


class ReferencePolicy(nn.Module):
    """mu_psi_z(r | o_t^z), o_t^z = Enc_r(X^z, G^z, S-hat^z)."""

    def __init__(self, n_param_groups: int, n_groups: int, d_robot: int, hidden: int, n_refs: int) -> None:
        super().__init__()
        self.enc = GroupMLP(n_param_groups, n_groups, [d_robot, hidden, hidden], final_activation=True)
        self.head = GroupMLP(n_param_groups, n_groups, [hidden, hidden, n_refs])

    def forward(self, robots: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """robots (Z, M, n, d_robot) own features + S-hat patches, mask (Z, M, n) ->
        logits (Z, M, |R|)."""
        o = masked_mean(self.enc(robots), mask, dim=-2)
        return self.head(o)




def action_feature_index(obs_radius: int) -> np.ndarray:
    """(2, 5) column indices into ``robot_features`` of the action-aligned features:
    shortest-path progress of each action, and the same-group robot channel of the patch
    at the cell each action leads to (0 for Wait: the robot itself is blanked)."""
    return np.concatenate([progress_index(), robots_on_target_index(obs_radius)])


class LocalPolicy(nn.Module):
    """pi_theta_z(U | w_t^z), w_t^z = Enc_u(X^z, G^z, r): per-robot categoricals.

    logit(i, a) = head(h_i, group encoding, reference embedding)[a] + v_z . phi(i, a),
    where phi(i, a) are action-aligned features of robot i (``action_feature_index``) and
    v_z a per-group weight vector initialized at zero and scaled by ``ACTION_GAIN`` (a
    linear, action-aligned path the policy gradient can move quickly; docs/decisions/0107).
    """

    seeds = 1  # S > 1: parameters stacked for S seeds (see ``group_layers``)
    action_idx: torch.Tensor  # buffer (K, 5): the robot-feature column of each action's term

    def __init__(self, n_param_groups: int, n_groups: int, d_robot: int, hidden: int, n_refs: int,
                 obs_radius: int) -> None:
        super().__init__()
        p = n_param_groups
        self.enc = GroupMLP(p, n_groups, [d_robot, hidden, hidden], final_activation=True)
        self.ref_embed = nn.Parameter(torch.randn(p, n_refs, hidden) * 0.5)
        self.head = GroupMLP(p, n_groups, [3 * hidden, hidden, N_ACTIONS])
        self.register_buffer("action_idx", torch.from_numpy(action_feature_index(obs_radius)))
        self.action_w = nn.Parameter(torch.zeros(p, 1, 1, 1, self.action_idx.shape[0]))

    def forward(self, robots: torch.Tensor, mask: torch.Tensor, ref: torch.Tensor,
                action_mask: torch.Tensor) -> torch.Tensor:
        """robots (Z, M, n, d_robot) features of X^z and G^z only, mask (Z, M, n), ref
        (Z, M) int64, action_mask (Z, M, n, 5) bool -> log-probs (Z, M, n, 5)."""
        # With S stacked seeds the parameter groups are (Z S) and a row block holds M / S
        # episodes; every view below is free (seed-major rows, see ``group_layers``).
        zg, n = robots.shape[0] * self.seeds, robots.shape[2]
        m = robots.shape[1] // self.seeds
        h = self.enc(robots)
        pooled = masked_mean(h, mask, dim=-2)  # shared group encoding
        table = per_slice(self.ref_embed, zg)
        e = torch.gather(table, 1, ref.reshape(zg, m, 1).expand(zg, m, table.shape[-1]))  # (Z, M, H)
        logits = self._head(h, torch.cat([pooled, e.reshape(*pooled.shape[:2], -1)], dim=-1))
        # index_select of the flattened table: robots[..., action_idx] without advanced
        # indexing's overhead (the same values and layout, as in ``ActionPath``).
        k, a = self.action_idx.shape
        phi = robots.index_select(-1, self.action_idx.reshape(-1)).view(zg, m, n, k, a).transpose(-1, -2)
        logits = logits + ACTION_GAIN * (phi * self._action_w(zg)).sum(-1).reshape(logits.shape)
        return torch.log_softmax(logits.masked_fill(~action_mask, -1e9), dim=-1)

    def _action_w(self, zg: int) -> torch.Tensor:
        """v_z for zg parameter groups: broadcast when shared by every slice, else one per
        slice (shared parameters of S stacked seeds: seed s's v for slice z S + s)."""
        w: torch.Tensor = self.action_w
        return w if w.shape[0] in (1, zg) else per_slice(w, zg)

    def _head(self, h: torch.Tensor, ctx: torch.Tensor) -> torch.Tensor:
        """``head(cat([h_i, ctx]))`` for h (Z, M, n, H) and the per-row context ctx
        (Z, M, 2H) shared by the row's robots, without building the (Z, M, n, 3H) input:
        the first layer's context half is applied once per row and broadcast over the
        robots (equal up to float summation order; tests/algorithms/hierarchical)."""
        z, m, n, d = h.shape
        zg = z * self.seeds  # parameter groups; (Z, M) rows are (Z S, M / S) blocks
        first = cast(GroupLinear, self.head.layers[0])  # a ModuleList item is typed Module
        w, b = per_slice(first.weight, zg), per_slice(first.bias, zg)
        per_row = torch.baddbmm(b, ctx.reshape(zg, -1, ctx.shape[-1]), w[:, d:])  # context part + bias
        x = (torch.bmm(h.reshape(zg, -1, d), w[:, :d]).reshape(z, m, n, -1)
             + per_row.reshape(z, m, -1).unsqueeze(2))
        layers = self.head.layers
        for k in range(1, len(layers)):  # indexed: a slice of a ModuleList builds a new one per call
            x = layers[k](relu(x))
        return x


def group_major(gs: GroupStructure, per_robot: np.ndarray, fill: object = 0,
                device: torch.device | str = "cpu") -> torch.Tensor:
    """(M, N, ...) per robot -> (Z, M, n, ...) tensor grouped by slot, on ``device``."""
    g = gs.gather(per_robot, fill=fill)
    return torch.from_numpy(np.ascontiguousarray(np.swapaxes(g, 0, 1))).to(device)


def policy_forward(reference: ReferencePolicy, local: LocalPolicy, gs: GroupStructure, own: np.ndarray,
                   nbr: np.ndarray, controlled: np.ndarray, action_mask: np.ndarray,
                   ref: torch.Tensor | None, choice: ActionChoice | None = None,
                   ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Both levels for M rows: own (M, N, F) float16, nbr (M, N, P) uint8, controlled
    (M, N), action_mask (M, N, 5). Picks r by ``choice`` when ``ref`` is None. Returns r
    (Z, M), log mu (Z, M, |R|) and the local per-robot log-probs (Z, M, n, 5)."""
    dev = local.action_idx.device  # the networks' (algorithms/common/device.py); the rows come from the host
    feats_u = group_major(gs, own, device=dev).to(torch.float32)
    feats_r = torch.cat([feats_u, group_major(gs, nbr, device=dev).to(torch.float32)], dim=-1)
    mask = group_major(gs, controlled, fill=False, device=dev)
    amask = group_major(gs, action_mask, fill=True, device=dev)
    ref_logp = torch.log_softmax(reference(feats_r, mask), dim=-1)  # (Z, M, R)
    if ref is None:
        if choice is None:
            raise ValueError("policy_forward: give the reference r or the choice that picks it")
        ref = choice(ref_logp).to(dev)  # drawn on the host
    return ref, ref_logp, local(feats_u, mask, ref.to(dev), amask)
