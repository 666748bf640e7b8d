"""HierarchicalMethod: the paper's method (Sec. III, Algorithm 2) behind the Method contract.

Per step and for every group z of B episodes at once (no loop over groups or robots):
receive S_t^z over the lossy channel, update the GRU predictors and complete S-hat^z
(eq:predictor_input..eq:interaction_state_collection), sample (training) or take the
argmax (execution) of the reference r ~ mu_psi_z and the joint control U~ ~ pi_theta_z,
then run the safety filter (Algorithm 1) to get the executed U_t^z.

Training (``update``, see ``training.py``): the centralized critic V_omega on the global
state gives the team advantage, used for both policy levels (eq:losses), Adam; the GRU
predictors are trained with their own supervised loss and optimizer (eq:gru_pred_loss).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import torch
from pydantic import Field

from algorithms.base import LearnedParams, Method, sample_categorical
from algorithms.common.episodes import Decision, EpisodeBatch
from algorithms.common.trainer import CRITIC_FEATURES, CentralCritic, RolloutBuffer, critic_features
from algorithms.hierarchical.messages import (
    CTRL,
    MSG_DIM,
    POS,
    PRESENT,
    group_messages,
    group_structure,
)
from algorithms.hierarchical.policies import (
    LocalPolicy,
    ReferencePolicy,
    neighbor_patch_size,
    neighbor_patches,
)
from algorithms.hierarchical.predictor import (
    GroupPredictor,
    PredictorState,
    SnapToFree,
    initial_state,
    rollout_step,
)
from algorithms.hierarchical.safety_filter import SafetyFilter
from algorithms.hierarchical.training import policy_update, predictor_update
from envs.actions import N_ACTIONS, WAIT
from envs.channel import GroupChannel
from envs.config import EnvConfig
from envs.observations import PatchExtractor, feature_size, robot_features


class HierarchicalParams(LearnedParams):
    """Hyperparameters of the hierarchical method (defaults: docs/decisions.md)."""

    batch_episodes: int = Field(8, ge=1, description="episodes per update, batched in one process")
    ref_size: int = Field(8, ge=1, description="|R_z|, size of the abstract reference space")
    search_radius: int = Field(2, ge=0, description="safety filter search radius L")
    c_max: int = Field(500, ge=1, description="safety filter candidate budget C_max")
    safety_filter: bool = Field(True, description="run Algorithm 1 before execution")
    predictor_hidden: int = Field(64, ge=4, description="GRU hidden size per link")
    predictor_embed: int = Field(32, ge=4, description="message embedding width of the predictor")
    obs_radius: int = Field(2, ge=1, description="half-width k of the (2k+1)^2 local patches")
    predictor_lr: float = Field(1e-3, gt=0, description="Adam learning rate of the GRU predictors")
    share_params: bool = Field(False, description="one parameter set for all groups (paper: per group)")
    update_chunk: int = Field(128, ge=1, description="time steps per backward pass in the update")
    execution: Literal["argmax", "sample"] = Field(
        "argmax", description="evaluation controls: argmax at both levels (SPEC), or sampled")


@dataclass
class Controller:
    """Per-batch controller state (one per ``run``)."""

    channel: GroupChannel
    patch: PatchExtractor
    pred: PredictorState | None = None
    buffer: RolloutBuffer | None = None
    running: np.ndarray | None = None  # (B,) episodes running before the current step
    gen: torch.Generator | None = None  # sampled evaluation: its own stream, from batch.rng


class HierarchicalMethod(Method):
    name = "hierarchical"
    Params = HierarchicalParams

    def __init__(self, env: EnvConfig, params: dict[str, Any] | None = None, seed: int = 0) -> None:
        super().__init__(env, params, seed)
        p: HierarchicalParams = self.params  # type: ignore[assignment]
        self.gs = group_structure(env)
        z = env.groups
        pz = 1 if p.share_params else z
        self.d_own = feature_size(p.obs_radius)
        self.d_nbr = neighbor_patch_size(p.obs_radius)
        self.reference = ReferencePolicy(pz, z, self.d_own + self.d_nbr, p.hidden, p.ref_size)
        self.local = LocalPolicy(pz, z, self.d_own, p.hidden, p.ref_size, p.obs_radius)
        self.predictor = GroupPredictor(pz, z, self.layout.shape, p.predictor_hidden, p.predictor_embed)
        self.critic = CentralCritic(p.critic_hidden)
        self.opt_policy = torch.optim.Adam(
            list(self.reference.parameters()) + list(self.local.parameters()), lr=p.lr)
        self.opt_critic = torch.optim.Adam(self.critic.parameters(), lr=p.critic_lr)
        self.opt_predictor = torch.optim.Adam(self.predictor.parameters(), lr=p.predictor_lr)
        self.filter = SafetyFilter(self.layout, p.search_radius, p.c_max)
        self.snap = SnapToFree(self.layout)

    def modules(self) -> dict[str, torch.nn.Module | torch.optim.Optimizer]:
        return {
            "reference": self.reference, "local": self.local, "predictor": self.predictor,
            "critic": self.critic, "opt_policy": self.opt_policy, "opt_critic": self.opt_critic,
            "opt_predictor": self.opt_predictor,
        }

    # ------------------------------------------------------------- controller
    def begin(self, batch: EpisodeBatch, greedy: bool) -> Controller:
        p: HierarchicalParams = self.params  # type: ignore[assignment]
        core = batch.core
        ctrl = Controller(GroupChannel(self.env, core.batch, batch.rng), PatchExtractor(core, p.obs_radius))
        if greedy and p.execution == "sample":  # never touch the training stream
            ctrl.gen = torch.Generator().manual_seed(int(batch.rng.integers(2**62)))
        if not greedy:
            b, n, zz = core.batch, core.n, self.env.groups
            slots, links = self.gs.n_slots, self.gs.neighbors.shape[1]
            ctrl.buffer = RolloutBuffer(self.env.horizon, b, {
                "own": ((n, self.d_own), np.float16),
                "nbr": ((n, self.d_nbr), np.uint8),
                "controlled": ((n,), np.bool_),
                "action_mask": ((n, N_ACTIONS), np.bool_),
                "ref": ((zz,), np.int64),
                "proposed": ((n,), np.int64),
                "critic": ((n, CRITIC_FEATURES), np.float32),
                "msgs": ((zz, slots, MSG_DIM), np.float32),
                "avail": ((zz, links), np.bool_),
                "age": ((zz, links), np.int64),
            })
        return ctrl

    def decide(self, batch: EpisodeBatch, state: Controller, greedy: bool) -> Decision:
        core, gs = batch.core, self.gs
        gen = state.gen if state.gen is not None else self.torch_gen
        greedy = greedy and state.gen is None
        state.running = ~core.ended
        # Channel and predictor: S_t^z, A_t^{z',z} -> S-hat_t^z.
        avail = gs.link_availability(state.channel.step())  # (B, Z, K)
        own_msgs = group_messages(core, gs)  # (B, Z, n, D)
        link_msgs = gs.links(own_msgs)  # (B, Z, K, n, D)
        if state.pred is None:
            state.pred = initial_state(self.predictor, link_msgs)
        with torch.no_grad():
            m_hat = rollout_step(self.predictor, state.pred, link_msgs, avail, own_msgs)
        sender_slots = gs.slot_valid[np.maximum(gs.neighbors, 0)] & gs.link_valid[..., None]  # (Z, K, n)
        present = (m_hat[..., PRESENT] > 0.5) & sender_slots[None]
        cells = self.snap(m_hat[..., POS])  # (B, Z, K, n)
        heading = self.layout.next_cell[cells, m_hat[..., CTRL].argmax(-1)]
        lost = ~avail & gs.link_valid[None]
        sq_err, n_lost = self._prediction_error(cells, link_msgs, lost, sender_slots)

        # Policies: r ~ mu(. | Enc_r(X, G, S-hat)), U~ ~ pi(. | Enc_u(X, G, r)).
        own = robot_features(core, state.patch, gs.groups).astype(np.float16)
        nbr = neighbor_patches(state.patch, gs, cells, present, heading)
        controlled = ~core.done & state.running[:, None]
        action_mask = self.layout.move_valid[core.pos]
        with torch.no_grad():
            ref, _, logp = self.policy_forward(own, nbr, controlled, action_mask, ref=None,
                                               greedy=greedy, gen=gen)
            proposed_g = sample_categorical(logp, greedy, gen)  # (Z, B, n)
        proposed = np.where(controlled, gs.scatter(proposed_g.numpy().swapaxes(0, 1), core.n), WAIT)

        dec = Decision(actions=proposed, proposed=proposed, payload=float(state.channel.payload_hier),
                       pred_sq_err=sq_err, pred_count=n_lost)
        if self.params.safety_filter:  # type: ignore[attr-defined]
            self._apply_filter(core, cells, present, controlled, proposed, logp, dec)
        if state.buffer is not None:
            state.buffer.add(own=own, nbr=nbr, controlled=controlled, action_mask=action_mask,
                             ref=ref.numpy().T, proposed=proposed, critic=critic_features(core),
                             msgs=own_msgs, avail=avail, age=state.pred.age)
        return dec

    def observe(self, batch: EpisodeBatch, state: Controller, result: Any) -> None:
        if state.buffer is not None:
            state.buffer.reward(result.reward, state.running)

    # ---------------------------------------------------------------- helpers
    def group_major(self, per_robot: np.ndarray, fill: object = 0) -> torch.Tensor:
        """(M, N, ...) per robot -> (Z, M, n, ...) tensor grouped by slot."""
        g = self.gs.gather(per_robot, fill=fill)
        return torch.from_numpy(np.ascontiguousarray(np.swapaxes(g, 0, 1)))

    def policy_forward(self, own: np.ndarray, nbr: np.ndarray, controlled: np.ndarray,
                       action_mask: np.ndarray, ref: torch.Tensor | None, greedy: bool = False,
                       gen: torch.Generator | None = None,
                       ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Both levels for M rows: own (M, N, F) float16, nbr (M, N, P) uint8, controlled
        (M, N), action_mask (M, N, 5). Samples r when ``ref`` is None. Returns r (Z, M),
        log mu (Z, M, |R|) and the local per-robot log-probs (Z, M, n, 5)."""
        feats_u = self.group_major(own).to(torch.float32)
        feats_r = torch.cat([feats_u, self.group_major(nbr).to(torch.float32)], dim=-1)
        mask = self.group_major(controlled, fill=False)
        amask = self.group_major(action_mask, fill=True)
        ref_logp = torch.log_softmax(self.reference(feats_r, mask), dim=-1)  # (Z, M, R)
        if ref is None:
            ref = sample_categorical(ref_logp, greedy, gen if gen is not None else self.torch_gen)
        return ref, ref_logp, self.local(feats_u, mask, ref, amask)

    def _apply_filter(self, core: Any, cells: np.ndarray, present: np.ndarray, controlled: np.ndarray,
                      proposed: np.ndarray, logp: torch.Tensor, dec: Decision) -> None:
        gs, b, z = self.gs, core.batch, self.env.groups
        g = b * z
        blocked = self.filter.blocked_cells(cells.reshape(g, -1), present.reshape(g, -1))
        res = self.filter(
            gs.gather(core.pos).reshape(g, -1), gs.gather(core.occupying, fill=False).reshape(g, -1),
            gs.gather(controlled, fill=False).reshape(g, -1), gs.gather(proposed, fill=WAIT).reshape(g, -1),
            logp.numpy().swapaxes(0, 1).reshape(g, -1, N_ACTIONS).astype(np.float64), blocked,
        )
        dec.actions = np.where(controlled, gs.scatter(res.actions.reshape(b, z, -1), core.n), WAIT)
        dec.candidates = res.examined.reshape(b, z).sum(1)
        dec.filter_calls = res.called.reshape(b, z).sum(1)
        dec.fallbacks = res.fallback.reshape(b, z).sum(1)

    def _prediction_error(self, cells: np.ndarray, link_msgs: np.ndarray, lost: np.ndarray,
                          sender_slots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per episode: summed over lost links, the mean squared position error (cells^2)
        of the snapped prediction over the sender's robots on the floor; and the count."""
        true_rc = link_msgs[..., POS]
        pred_rc = self.layout.cells[cells].astype(np.float32)
        on = (link_msgs[..., PRESENT] > 0) & sender_slots[None]
        err = (((pred_rc - true_rc) ** 2).sum(-1) * on).sum(-1) / np.maximum(on.sum(-1), 1)
        return (err * lost).sum(axis=(1, 2)), lost.sum(axis=(1, 2)).astype(np.float64)

    # ---------------------------------------------------------------- update
    def update(self, state: Controller) -> dict[str, float]:
        assert state.buffer is not None
        losses = policy_update(self, state.buffer)
        losses.update(predictor_update(self, state.buffer))
        return losses
