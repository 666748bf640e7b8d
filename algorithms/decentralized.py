"""Fully decentralized MARL baseline (paper Sec. IV "fully decentralized MARL baseline").

Every robot selects its own control from its robot-level observation plus the messages
received from all other robots over lossy all-to-all links, without the group hierarchy:

* observation o_t^i = [own state and local view of shelves and nearby robots
  (``local_view``, the same per-robot view as every learned method), egocentric maps of
  the last received messages of every other robot (``AllToAllBoard``)];
  the message maps sum-pool one-hot relative positions, so any N uses the same network;
* actor pi_theta(u^i | o^i): one MLP with parameters shared by all robots and **no robot
  index one-hot** (robots are interchangeable; a one-hot would tie the network to N);
  moves into shelves are masked (the environment's action mask);
* trained with the paper's trainer (algorithms/common/trainer.py): Monte-Carlo team
  return (eq:training_return), centralized critic V_omega(X_t) and team advantage
  A_t = G_t - V(X_t) (eq:advantage), actor loss -A_t sum_i log pi(u_t^i | o_t^i) and
  critic loss (V - G)^2 (eq:losses), Adam (``critic_update``, ``clip_and_step``).
  Rollouts run under no_grad into a
  ``RolloutBuffer``, which also keeps the actor's two hidden activations (paper protocol);
  the update backpropagates from them over the active robot-steps (chunked only to bound
  memory: the gradient is the same), with no re-forward of the MLP, bit for bit
  (docs/decisions/0217);
* payload N (N - 1) d_m scalars per step (Sec. III-A, C_dec);
* ``safety_filter=True`` runs the hierarchical method's filter (Algorithm 1,
  eq:safety_conditions) with every robot its own group, on the received (possibly stale)
  positions of the others; the policy gradient uses the sampled (proposed) controls.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

import numpy as np
import torch
from pydantic import Field
from torch import nn
from torch.nn import functional as F

from algorithms.base import BASELINE, LearnedParams, Method, masked_logits
from algorithms.common.action_path import ActionPath, progress_index
from algorithms.common.all_to_all import OFF_FLOOR, AllToAllBoard, map_feature_size
from algorithms.common.diagnostics import KLProbe, probe_rows, wait_share
from algorithms.common.episodes import Decision, EpisodeBatch
from algorithms.common.execution import ActionChoice
from algorithms.common.ppo import (
    MAPPO,
    PPOBatch,
    RobotCritic,
    mappo_critic,
    ppo_actor_update,
    robot_rewards,
    update_generator,
)
from algorithms.common.robot_obs import (
    HISTORY_SIZE,
    action_mask_into,
    local_view_into,
    local_view_size,
    own_history_into,
    robots_on_target_index,
)
from algorithms.common.seed_stack import OwnNetworksStack
from algorithms.common.trainer import (
    CentralCritic,
    RolloutBuffer,
    clip_and_step,
    critic_shapes,
    critic_update,
    store_critic_inputs,
)
from algorithms.hierarchical.safety_filter import SafetyFilter
from algorithms.presets import Preset
from envs.actions import DELTAS, N_ACTIONS
from envs.observations import PatchExtractor


class DecentralizedParams(LearnedParams):
    """Hyperparameters of the decentralized baseline; the shared ones (hidden = width of the
    actor's two hidden layers, lr = actor Adam rate, ...) come from ``LearnedParams``."""

    patch_radius: int = Field(2, ge=1, le=6, description="k of the (2k+1)^2 local view and message maps")
    action_path: bool = Field(True, description="linear action-aligned logit path, as the hierarchical policy's")
    safety_filter: bool = Field(False, description="apply Algorithm 1 with each robot its own group")
    search_radius: int = Field(2, ge=0, description="safety filter search radius L (with the filter)")
    c_max: int = Field(500, ge=1, description="safety filter candidate budget C_max (with the filter)")
    chunk_rows: int = Field(65536, ge=256, description="robot-steps per backward chunk (memory only)")


def action_feature_index(radius: int) -> np.ndarray:
    """(4, 5) columns of the observation holding, for each action, its shortest-path
    progress, the sensed robots (local view) and the message maps' robots (received
    positions; cells their received controls lead to) on the cell the action leads to:
    the action-aligned features phi."""
    side = 2 * radius + 1
    maps = local_view_size(radius) + HISTORY_SIZE  # start of the message maps
    cells = [(radius + dr) * side + (radius + dc) for dr, dc in DELTAS.tolist()]
    return np.concatenate([progress_index(), robots_on_target_index(radius),
                           [[maps + c for c in cells]], [[maps + side * side + c for c in cells]]])


class DecentralizedActor(nn.Module):
    """pi_theta(u | o): (..., F) observations and (..., 5) masks -> (..., 5) masked logits.

    logit(a) = MLP(o)[a] + ACTION_GAIN v . phi(o, a): the linear, action-aligned path of
    the hierarchical local policy (``ActionPath``, v = 0 at init), so neither method learns
    the obvious "progress and free target cell" rule more slowly (docs/decisions/0136).
    """

    def __init__(self, n_in: int, hidden: int, radius: int, action_path: bool = True) -> None:
        super().__init__()
        self.net = nn.Sequential(nn.Linear(n_in, hidden), nn.ReLU(), nn.Linear(hidden, hidden),
                                 nn.ReLU(), nn.Linear(hidden, N_ACTIONS))
        self.path = ActionPath(action_feature_index(radius)) if action_path else None

    def forward(self, obs: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        if not torch.is_grad_enabled():
            return self.rollout_logits(obs, mask)
        logits = self.net(obs)
        if self.path is not None:
            logits = self.path(obs, logits)
        return masked_logits(logits, mask)

    def layers(self) -> tuple[nn.Linear, nn.Linear, nn.Linear]:
        """The MLP's three linear layers."""
        lin0, _, lin1, _, lin2 = cast("tuple[nn.Linear, nn.ReLU, nn.Linear, nn.ReLU, nn.Linear]", self.net)
        return lin0, lin1, lin2

    def rollout_logits(self, obs: torch.Tensor, mask: torch.Tensor,
                       hidden_out: tuple[torch.Tensor, torch.Tensor] | None = None) -> torch.Tensor:
        """``forward`` without autograd: the same ops, ReLU and the mask applied in place on
        fresh intermediates, no module-call overhead (bit-identical;
        tests/algorithms/test_baseline_fast_paths.py). With ``hidden_out`` (e.g. two rollout
        buffer rows) both hidden layers' activations are copied there for the update
        (``logits_from_hidden``)."""
        lin0, lin1, lin2 = self.layers()
        x = F.linear(obs, lin0.weight, lin0.bias).relu_()
        if hidden_out is not None:
            hidden_out[0].copy_(x)
        x = F.linear(x, lin1.weight, lin1.bias).relu_()
        if hidden_out is not None:
            hidden_out[1].copy_(x)
        logits = F.linear(x, lin2.weight, lin2.bias)
        if self.path is not None:
            logits = self.path(obs, logits)
        return logits.masked_fill_(~torch.as_tensor(mask, dtype=torch.bool), -1e9)

    def logits_from_hidden(self, obs: torch.Tensor, hidden: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """``forward`` from the last hidden layer's activations kept by the rollout
        (``hidden`` = ReLU(lin1(ReLU(lin0(obs)))), a leaf that requires grad): the same ops
        from there on, so autograd gives the same gradients of lin2, the action path and
        ``hidden``; ``hidden_backward`` then gives lin1's and lin0's (no re-forward)."""
        logits = self.layers()[2](hidden)
        if self.path is not None:
            logits = self.path(obs, logits)
        return masked_logits(logits, mask)

    def hidden_backward(self, obs: torch.Tensor, hidden: tuple[torch.Tensor, torch.Tensor]) -> None:
        """Accumulate lin1's and lin0's gradients from ``hidden[1].grad`` as autograd's ReLU
        and addmm backward would: threshold_backward on the ReLU output, grad^T input for
        the weight, the row sum for the bias, grad W for the layer's input (all row-major,
        as in the re-forward), so the sum over chunks is the same float sequence as a full
        backward (scripts/train_hashes.py)."""
        lin0, lin1, _ = self.layers()
        grad = hidden[1].grad
        assert grad is not None
        for lin, out, inp in ((lin1, hidden[1], hidden[0]), (lin0, hidden[0], obs)):
            grad = torch.ops.aten.threshold_backward(grad, out.detach(), 0)
            for param, g in ((lin.weight, grad.t().mm(inp)), (lin.bias, grad.sum(0))):
                if param.grad is None:
                    param.grad = g
                else:
                    param.grad += g
            if lin is lin1:
                grad = grad.mm(lin.weight.detach())


@dataclass
class DecentralizedState:
    """Controller state of B episodes (``buffer`` only while training)."""

    board: AllToAllBoard
    patch: PatchExtractor
    buffer: RolloutBuffer | None
    running: np.ndarray  # (B,) episodes running before the current step
    collided: np.ndarray  # (B, N) robots stopped by a conflict at the previous step


class DecentralizedMethod(OwnNetworksStack, Method):
    name = "decentralized"
    display_name = "Decentralized"
    color = "#de8f05"
    legend_rank = 1
    paper_role = BASELINE  # compared with the paper's method (Sec. IV)
    line_style = "--"
    payload_model = "all-to-all robot messages: N (N - 1) d_m per step (Sec. III-A, C_dec)"
    Params = DecentralizedParams
    # "tuned": the winner of the committed study reproduction/studies/tuned-decentralized (decisions
    # 0215, 0245); tests/studies/test_published_presets.py checks these values against it.
    presets = {"tuned": Preset({"protocol": "mappo", "ppo_lr": 0.001, "entropy_coef": 0.01, "hidden": 128,
                                "critic_hidden": 128, "patch_radius": 2, "action_path": False},
                               source="studies/definitions/decentralized.toml")}
    params: DecentralizedParams

    def __init__(self, env, params=None, seed: int = 0, device=None) -> None:
        super().__init__(env, params, seed, device)
        p = self.params
        self.n_obs = (local_view_size(p.patch_radius) + HISTORY_SIZE
                      + map_feature_size(p.patch_radius))
        self.actor = DecentralizedActor(self.n_obs, p.hidden, p.patch_radius, p.action_path)
        self.mappo = p.protocol == MAPPO
        self.critic: CentralCritic | RobotCritic = RobotCritic(p.critic_hidden) if self.mappo \
            else CentralCritic(p.critic_hidden)
        self.actor_opt = torch.optim.Adam(self.actor.parameters(), lr=p.ppo_lr if self.mappo else p.lr)
        self.critic_opt = torch.optim.Adam(self.critic.parameters(), lr=p.critic_lr)
        self.filter = SafetyFilter(self.layout, p.search_radius, p.c_max) if p.safety_filter else None
        self.place_modules()

    # ------------------------------------------------------------ seed stacking
    # A stack view (OwnNetworksStack) runs the environment, observations, channel and filter
    # on all S B episodes at once, and each seed's actor computes the logits of its own B
    # episodes (the shapes of its own run; its activations go to its rows of the buffer).
    STACK_NET = "actor"

    def rollout_logits(self, obs: torch.Tensor, mask: torch.Tensor,
                       hidden: tuple[torch.Tensor, torch.Tensor] | None) -> torch.Tensor:
        """The actor's rollout logits of the batch; a stack view's from each seed's actor on
        its own episodes."""
        if self._seeds is None:
            return self.actor.rollout_logits(obs, mask, hidden)
        return torch.cat([actor.rollout_logits(obs[lo:hi], mask[lo:hi],
                                               None if hidden is None else (hidden[0][lo:hi], hidden[1][lo:hi]))
                          for actor, lo, hi in self._seeds])

    def modules(self) -> dict[str, nn.Module | torch.optim.Optimizer]:
        return {"actor": self.actor, "critic": self.critic,
                "actor_opt": self.actor_opt, "critic_opt": self.critic_opt}

    # ------------------------------------------------------------- controller
    def begin(self, batch: EpisodeBatch, choice: ActionChoice) -> DecentralizedState:
        core, env, p = batch.core, self.env, self.params
        b, n = core.pos.shape
        loss = batch.open_channel("robots")
        buffer = None
        if choice.training:
            buffer = RolloutBuffer(env.horizon, b, {
                "obs": ((n, self.n_obs), np.float32), "mask": ((n, N_ACTIONS), bool),
                "actions": ((n,), np.int64), "active": ((n,), bool), **critic_shapes(n),
                **({"robot_reward": ((n,), np.float32), "logp": ((n,), np.float32)} if self.mappo
                   else {"hidden0": ((n, p.hidden), np.float32),  # the actor's activations
                         "hidden1": ((n, p.hidden), np.float32)}),
            })
        state = DecentralizedState(AllToAllBoard(core, loss, p.patch_radius),
                                   PatchExtractor(core, p.patch_radius), buffer, ~core.ended,
                                   np.zeros((b, n), dtype=bool))
        return state

    def observe_robots(self, state: DecentralizedState, out: np.ndarray | None = None) -> np.ndarray:
        """(B, N, F) observations from the core and the received messages, written into
        ``out`` (e.g. the rollout buffer's row) when given:
        [local_view, own_history, message maps]."""
        core = state.board.core
        if out is None:
            out = np.empty(core.pos.shape + (self.n_obs,), dtype=np.float32)
        lv = local_view_size(self.params.patch_radius)
        local_view_into(core, state.patch, out[..., :lv])
        own_history_into(core, state.collided, out[..., lv:lv + HISTORY_SIZE])
        state.board.features(out[..., lv + HISTORY_SIZE:])
        return out

    def decide(self, batch: EpisodeBatch, state: DecentralizedState, choice: ActionChoice) -> Decision:
        core, buf = batch.core, state.buffer
        delivered = state.board.receive()  # (B, N_send, N_recv)
        # Training: observations, masks and critic inputs go straight into the buffer row.
        obs = self.observe_robots(state, None if buf is None else buf.row("obs"))
        mask = np.empty(core.pos.shape + (N_ACTIONS,), dtype=bool) if buf is None else buf.row("mask")
        action_mask_into(core, mask)
        with torch.inference_mode():  # rollouts never backpropagate (the update recomputes)
            hidden = None if buf is None or "hidden0" not in buf.data else \
                (torch.from_numpy(buf.row("hidden0")), torch.from_numpy(buf.row("hidden1")))
            dev = self.device
            logits = self.rollout_logits(torch.from_numpy(obs).to(dev), torch.from_numpy(mask).to(dev), hidden)
            actions = choice(logits).numpy()
            if buf is not None and "logp" in buf.data:  # mappo: the rollout policy's log-probs
                buf.row("logp")[...] = torch.log_softmax(logits, -1).cpu().gather(
                    -1, torch.from_numpy(actions)[..., None]).squeeze(-1).numpy()
        state.running = ~core.ended
        if buf is not None:
            store_critic_inputs(buf, core, self.env.horizon)
            buf.add(actions=actions, active=~core.done & state.running[:, None])
        dec = Decision(actions=actions, payload=float(state.board.payload), robot_links=delivered)
        if self.filter is not None:
            self.apply_filter(self.filter, state.board, logits, dec)
        return dec

    def apply_filter(self, filt: SafetyFilter, board: AllToAllBoard, logits: torch.Tensor,
                     dec: Decision) -> None:
        """Algorithm 1 with every robot its own group (G = B N groups of one robot): the
        neighbours are the other robots at their last received positions (stale under
        loss; a robot known to have left the floor is no neighbour); the candidates are
        ordered by the actor's probabilities. Sets executed actions and filter counts."""
        core = board.core
        b, n = core.pos.shape
        g = b * n
        present = (board.ctl != OFF_FLOOR) & board.others  # (B, N_recv, N_send)
        blocked = filt.blocked_cells(board.pos.reshape(g, n), present.reshape(g, n))
        controlled = ~core.done & ~core.ended[:, None]
        logp = torch.log_softmax(logits, dim=-1).double().cpu().numpy().reshape(g, 1, N_ACTIONS)
        res = filt(core.pos.reshape(g, 1), core.occupying.reshape(g, 1),
                          controlled.reshape(g, 1), dec.actions.reshape(g, 1), logp, blocked)
        dec.proposed = dec.actions
        dec.actions = np.where(controlled, res.actions.reshape(b, n), dec.actions)
        dec.candidates = res.examined.reshape(b, n).sum(1)
        dec.filter_calls = res.called.reshape(b, n).sum(1)
        dec.fallbacks = res.fallback.reshape(b, n).sum(1)

    def observe(self, batch: EpisodeBatch, state: DecentralizedState, result: Any) -> None:
        state.collided = result.collision
        if state.buffer is not None:
            if self.mappo:
                state.buffer.add(robot_reward=robot_rewards(result))
            state.buffer.reward(result.reward, state.running)

    # ---------------------------------------------------------------- update
    def update(self, state: DecentralizedState) -> dict[str, float]:
        """One actor and one critic Adam step from the finished batch (eq:losses); under
        ``protocol="mappo"`` the clipped surrogate of algorithms/common/ppo.py."""
        buf, p = state.buffer, self.params
        assert buf is not None, "update() needs a training rollout"
        if isinstance(self.critic, RobotCritic):
            return self.mappo_update(buf)
        crit = critic_update(self.critic, self.critic_opt, buf, p.normalize_advantage, p.max_grad_norm)
        adv, n = crit.adv, crit.n

        # Actor: -sum_{t,b} A_t sum_i log pi(u_t^i | o_t^i) / n over the active robot-steps.
        active = buf.data["active"][: buf.t]  # (T, B, N)
        sel = np.flatnonzero(active)  # the active robot-steps, in C order, found once

        def rows_of(key: str) -> np.ndarray:  # = buf.data[key][: buf.t][active]
            data = buf.data[key][: buf.t]
            return np.take(data.reshape(active.size, *data.shape[3:]), sel, axis=0)

        obs, act_mask = rows_of("obs"), rows_of("mask")
        hidden0, hidden1 = rows_of("hidden0"), rows_of("hidden1")
        dev = self.device
        actions = torch.from_numpy(rows_of("actions")).to(dev)
        weight = np.take(np.broadcast_to(adv.cpu().numpy()[..., None], active.shape).reshape(-1), sel) / float(n)
        weight_t = torch.from_numpy(np.ascontiguousarray(weight, dtype=np.float32)).to(dev)
        rows = obs.shape[0]
        self.actor_opt.zero_grad()
        actor_total, entropy_total = 0.0, 0.0
        for lo in range(0, rows, p.chunk_rows):
            sl = slice(lo, lo + p.chunk_rows)
            # The rollout's hidden activations instead of a re-forward (bit for bit).
            obs_t = torch.from_numpy(obs[sl]).to(dev)
            kept = (torch.from_numpy(hidden0[sl]).to(dev), torch.from_numpy(hidden1[sl]).to(dev).requires_grad_())
            logp_all = torch.log_softmax(self.actor.logits_from_hidden(
                obs_t, kept[1], torch.from_numpy(act_mask[sl]).to(dev)), dim=-1)
            logp = logp_all.gather(-1, actions[sl, None]).squeeze(-1)
            entropy = -(logp_all.exp() * logp_all).sum(-1)
            loss = -(weight_t[sl] * logp).sum() - p.entropy_coef * entropy.sum() / max(rows, 1)
            loss.backward()
            self.actor.hidden_backward(obs_t, kept)
            actor_total += float(-(weight_t[sl] * logp.detach()).sum())
            entropy_total += float(entropy.detach().sum())
        probe = self.kl_probe(obs, act_mask)
        grad_norm = clip_and_step(self.actor_opt, p.max_grad_norm)
        return {"actor_loss": actor_total, "critic_loss": crit.loss,
                "entropy": entropy_total / max(rows, 1), "grad_norm": grad_norm,
                "return_mean": float((crit.returns * crit.mask).sum() / n),
                **crit.diagnostics(), "diag_entropy": entropy_total / max(rows, 1),
                "diag_grad_norm": grad_norm, "diag_kl": probe.kl(),
                "diag_wait_share": wait_share(actions.cpu().numpy(), np.ones(rows, dtype=bool))}

    def kl_probe(self, obs: np.ndarray, act_mask: np.ndarray) -> KLProbe:
        """The actor's log-probabilities on a strided subset of the update's robot-steps,
        for the KL across the step (diagnostics only)."""
        idx = probe_rows(obs.shape[0])
        o, m = torch.from_numpy(obs[idx]).to(self.device), torch.from_numpy(act_mask[idx]).to(self.device)
        return KLProbe(lambda: (torch.log_softmax(self.actor(o, m), dim=-1), None))

    def mappo_update(self, buf: RolloutBuffer) -> dict[str, float]:
        """``protocol="mappo"``: the critic's GAE targets and advantages (per robot or team,
        ``credit``), then the clipped surrogate over every active robot-step."""
        p = self.params
        assert isinstance(self.critic, RobotCritic)
        gen = update_generator(self.seed, self.iterations)
        crit = mappo_critic(self.critic, self.critic_opt, buf, p, gen=gen)
        active = buf.data["active"][: buf.t]
        sel = torch.from_numpy(np.flatnonzero(active))
        obs = torch.from_numpy(buf.data["obs"][: buf.t].reshape(active.size, -1)).to(self.device)
        masks = torch.from_numpy(buf.data["mask"][: buf.t].reshape(active.size, -1)).to(self.device)
        actions = torch.from_numpy(buf.data["actions"][: buf.t].reshape(-1)).to(self.device)
        adv = crit.robot_adv.reshape(-1)[sel][:, None]
        old = torch.from_numpy(buf.data["logp"][: buf.t].reshape(-1))[sel][:, None].to(self.device)

        def log_probs(ix: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
            rows = sel[ix]
            logp_all = torch.log_softmax(self.actor(obs[rows], masks[rows]), dim=-1)
            logp = logp_all.gather(-1, actions[rows, None])
            entropy = -(logp_all.exp() * logp_all).sum(-1, keepdim=True)
            return logp, entropy, torch.ones_like(logp)

        out = ppo_actor_update(PPOBatch(len(sel), log_probs, adv, old_log_probs=old), self.actor_opt, p.ppo_epochs,
                               p.ppo_minibatches, p.ppo_clip, p.entropy_coef, p.max_grad_norm, gen)
        return {**crit.losses, **out, "grad_norm": out["diag_grad_norm"], "entropy": out["diag_entropy"],
                "diag_wait_share": wait_share(buf.data["actions"][: buf.t], active)}
