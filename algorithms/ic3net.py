"""IC3Net (Singh, Jain and Sukhbaatar, ICLR 2019) in the warehouse, with lossy links.

IC3Net's architecture is the reference code's (IC3Net/IC3Net comm.py; facts in
shared/REFERENCES.md), per robot i and step t, with parameters shared by all robots:

* o_t^i = [``local_view`` (own state, shelves and nearby robots in the (2k+1)^2 window,
  the same per-robot view as every learned method; the reference environments give agents
  vision of nearby agents), own previous control and collision flag];
* e_t^i = W_e o_t^i (one linear encoder, no nonlinearity in recurrent mode);
* communication (``average_comm``): c_t^i = sum_j L_t[j, i] h_{t-1}^j / (alive_t - 1), the
  previous hidden states of the robots i hears, divided by the number of alive robots
  minus one as in the reference ``comm_mode="avg"``; the link mask
  L_t[j, i] = g_{t-1}^j g_{t-1}^i a^j a^i A_t[j, i] (j != i) combines the gate sampled at the
  previous step (a closed gate stops both sending and receiving, as in the reference
  code's mask g_i g_j), alive robots (a completed robot neither sends nor receives) and
  the lossy channel (each message dropped with probability p per directed link and step;
  under a message delay only the vectors that arrive the step they are sent are heard, a
  late one counts as lost: under a fixed delay d >= 1 nothing is heard, docs/decisions/0223);
* (h_t^i, c_t^i) = LSTMCell(e_t^i + C c_t^i, (h_{t-1}^i, c_{t-1}^i)), repeated
  ``comm_passes`` times (each pass communicates the newest hidden states);
* heads on h_t^i: action log-softmax (5, masked like every method's), gate log-softmax
  (2: silent / talk; nobody talks at t = 0), and with ``baseline="per_robot"`` a value V^i;
* the action logits get the linear action-aligned path every learned method has
  (``ActionPath``: each action's shortest-path progress and the robots in view on its
  target cell, v = 0 at init; ``action_path=True``, the default). Not in IC3Net's
  reference architecture: an equal-footing departure, measured in docs/decisions/0137; ``action_path=False`` is the
  reference's head.

Training, REINFORCE with a baseline on the Monte-Carlo team return G_t (eq:training_return,
gamma = 1), loss = -sum A (log pi(u) + log pi(g)) over alive robot-steps / environment
steps - entropy_coef * mean entropy per alive robot-step:

* ``baseline="central"`` (default): the shared trainer of every learned method (SPEC 3,
  algorithms/common/trainer.py): the centralized critic V_omega(X_t) with t/T, the team
  advantage A_t = G_t - V(X_t) (eq:advantage) shared by every robot and normalized like
  the other methods' (``team_advantage``), the critic stepped by ``critic_update``;
* ``baseline="per_robot"``: the reference's value head V^i on h_t^i (A = G_t - V^i,
  standardized per batch, the reference's ``normalize_rewards``; the head predicts
  running-normalized returns, ``ValueNorm``; + value_coef sum (V^i - G)^2);
* ``optimizer="adam"`` (default, the paper's) or ``"rmsprop"`` (the reference's, with
  ``rms_alpha``, ``rms_eps``); either is clipped at ``max_grad_norm`` (``clip_and_step``).

The reference setting is ``baseline="per_robot", optimizer="rmsprop", entropy_coef=0,
action_path=False`` with a very large ``max_grad_norm`` (the reference does not clip) and
``hidden=64``.

Rollouts run under no_grad and store inputs, link masks and samples in a
``RolloutBuffer``; the update replays the episode with gradients, batched over episodes
and robots, in chunks of ``detach_gap`` steps (truncated backpropagation through time as
in the reference ``detach_gap``; each chunk is backpropagated before the next so memory
is bounded). Payload: H scalars per communication pass on every directed link whose
sender and receiver both have their gate open and are alive (transmitted, lost or not).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import torch
from pydantic import Field
from torch import nn

from algorithms.base import BASELINE, LearnedParams, Method, masked_logits
from algorithms.common.action_path import ActionPath, progress_index
from algorithms.common.diagnostics import KLProbe, value_diagnostics, wait_share
from algorithms.common.episodes import Decision, EpisodeBatch
from algorithms.common.execution import ActionChoice
from algorithms.common.ppo import MAPPO, RobotCritic, robot_rewards
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
    CriticStep,
    RolloutBuffer,
    clip_and_step,
    critic_shapes,
    critic_update,
    mc_returns,
    store_critic_inputs,
)
from algorithms.common.value_norm import ValueNorm
from algorithms.ic3net_mappo import mappo_update
from algorithms.presets import Preset
from envs.actions import N_ACTIONS
from envs.channel import Channel
from envs.observations import PatchExtractor


class IC3NetParams(LearnedParams):
    """Hyperparameters; the shared ones (``hidden`` = H of encoder, LSTM and messages, lr,
    entropy_coef, max_grad_norm, normalize_advantage, critic) come from ``LearnedParams``;
    the architecture's own are the reference code's unless stated."""

    baseline: Literal["central", "per_robot"] = Field(
        "central", description="centralized critic V(X_t) of the shared trainer, or the reference's per-robot value "
                               "head")
    optimizer: Literal["adam", "rmsprop"] = Field(
        "adam", description="Adam (shared trainer) or RMSprop (reference) for the policy")
    comm_passes: int = Field(1, ge=1, description="communication passes per step")
    patch_radius: int = Field(2, ge=1, le=6, description="k of the (2k+1)^2 local view")
    rms_alpha: float = Field(0.97, gt=0, lt=1, description="RMSprop smoothing constant (optimizer=rmsprop)")
    rms_eps: float = Field(1e-6, gt=0, description="RMSprop epsilon (optimizer=rmsprop)")
    value_coef: float = Field(0.01, ge=0, description="weight of the value loss (baseline=per_robot)")
    value_norm: bool = Field(
        True, description="per-robot value head predicts running-normalized returns (MAPPO ValueNorm)")
    detach_gap: int = Field(50, ge=1, description="steps per truncated-BPTT chunk")
    gate: Literal["learned", "open", "closed"] = Field(
        "learned", description="learned talk/silent action (IC3Net), always talk (CommNet), never")
    action_path: bool = Field(
        True, description="the linear action-aligned path (progress, robots in view) every learned method has "
        "(False: IC3Net's reference action head)")
    communicate: bool = Field(True, description="False: no communication at all (reference comm_mask_zero)")


def average_comm(h: torch.Tensor, links: torch.Tensor, alive: torch.Tensor) -> torch.Tensor:
    """IC3Net's averaged communication vectors.

    h (B, N, H) previous hidden states; links (B, N_send, N_recv) 0/1 (gate, alive, loss
    and no self-link already applied); alive (B,) number of alive robots. Returns
    (B, N, H): c^i = sum_j links[j, i] h^j / (alive - 1) where alive > 1 (reference
    ``comm_mode="avg"``), the plain sum otherwise (then nothing is heard anyway).
    """
    denom = torch.where(alive > 1, alive - 1, torch.ones_like(alive)).to(h.dtype)
    # bmm of the transposed links: what einsum("bji,bjh->bih") runs, without its parsing;
    # float links (the rollout and the replay convert them in numpy) are used as they are.
    return torch.bmm(links.to(h.dtype).transpose(1, 2), h) / denom[:, None, None]


@functools.lru_cache(maxsize=8)
def _off_diagonal(n: int) -> np.ndarray:
    """(N, N) bool, False on the diagonal (no self-links); read-only, shared."""
    out = ~np.eye(n, dtype=bool)
    out.flags.writeable = False
    return out


class IC3NetPolicy(nn.Module):
    """Encoder, C per pass, LSTM cell and the action / gate / value heads."""

    def __init__(self, n_in: int, hidden: int, comm_passes: int, action_path: bool,
                 radius: int, value_head: bool) -> None:
        super().__init__()
        self.hidden = hidden
        self.encoder = nn.Linear(n_in, hidden)
        self.comm = nn.ModuleList([nn.Linear(hidden, hidden) for _ in range(comm_passes)])
        self.lstm = nn.LSTMCell(hidden, hidden)
        self.action_head = nn.Linear(hidden, N_ACTIONS)
        self.gate_head = nn.Linear(hidden, 2)
        self.value_head = nn.Linear(hidden, 1) if value_head else None  # baseline="per_robot"
        self.value_norm = ValueNorm()  # used when the method's ``value_norm`` is on
        index = np.concatenate([progress_index(), robots_on_target_index(radius)])
        self.path = ActionPath(index) if action_path else None

    def initial_state(self, b: int, n: int) -> tuple[torch.Tensor, torch.Tensor]:
        dev = self.encoder.weight.device
        return torch.zeros(b * n, self.hidden, device=dev), torch.zeros(b * n, self.hidden, device=dev)

    def forward(
        self, obs: torch.Tensor, mask: torch.Tensor, links: torch.Tensor, alive: torch.Tensor,
        hc: tuple[torch.Tensor, torch.Tensor],
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None, tuple[torch.Tensor, torch.Tensor]]:
        """One step. obs (B, N, F), mask (B, N, 5), links (B, N, N), alive (B,), hc ((B N, H) x2)
        -> action logits (B, N, 5), gate logits (B, N, 2), values (B, N) (None without the
        per-robot value head), new hc."""
        b, n, _ = obs.shape
        x = self.encoder(obs)  # (B, N, H)
        h, c = hc
        for comm in self.comm:
            heard = average_comm(h.view(b, n, self.hidden), links, alive)
            h, c = self.lstm((x + comm(heard)).view(b * n, self.hidden), (h, c))
        return (*self.heads(h.view(b, n, self.hidden), obs, mask), (h, c))

    def heads(self, hh: torch.Tensor, obs: torch.Tensor, mask: torch.Tensor,
              ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
        """Hidden states (..., N, H) -> masked action logits (..., N, 5), gate logits
        (..., N, 2) and per-robot values (..., N) (None without the value head)."""
        logits = self.action_head(hh)
        if self.path is not None:
            logits = self.path(obs, logits)
        values = None if self.value_head is None else self.value_head(hh).squeeze(-1)
        return masked_logits(logits, mask), self.gate_head(hh), values

    def replay(
        self, obs: torch.Tensor, mask: torch.Tensor, links: torch.Tensor, alive: torch.Tensor,
        hc: tuple[torch.Tensor, torch.Tensor],
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None, tuple[torch.Tensor, torch.Tensor]]:
        """``forward`` over a chunk of T steps (inputs with a leading (T,) axis), outputs
        stacked (T, B, N, ...). The encoder and the heads run once over the chunk; only the
        communication and the LSTM cell go step by step. Equal to T ``forward`` calls up to
        the float rounding of the larger matmuls (tests/algorithms/test_ic3net.py)."""
        tc, b, n, _ = obs.shape
        xs = self.encoder(obs).unbind(0)  # T x (B, N, H); unbind: one backward, not T
        h, c = hc
        hs = []
        for t in range(tc):
            for comm in self.comm:
                heard = average_comm(h.view(b, n, self.hidden), links[t], alive[t])
                h, c = self.lstm((xs[t] + comm(heard)).view(b * n, self.hidden), (h, c))
            hs.append(h)
        return (*self.heads(torch.stack(hs).view(tc, b, n, self.hidden), obs, mask), (h, c))


@dataclass
class IC3NetState:
    patch: PatchExtractor
    loss: Channel
    buffer: RolloutBuffer | None
    hc: tuple[torch.Tensor, torch.Tensor]
    gate: np.ndarray  # (B, N) bool, talk at the next step (sampled at this one)
    collided: np.ndarray  # (B, N) robots stopped by a conflict at the previous step
    running: np.ndarray  # (B,)
    chunk_hc: list[tuple[torch.Tensor, torch.Tensor]] = field(default_factory=list)  # mappo: hc at chunk starts


class IC3NetMethod(OwnNetworksStack, Method):
    name = "ic3net"
    display_name = "IC3Net"
    color = "#029e73"
    legend_rank = 2
    paper_role = BASELINE  # compared with the paper's method (Sec. IV)
    line_style = "-."
    payload_model = "communication vectors of the robots whose gate is open, counted as sent"
    Params = IC3NetParams
    # "tuned": the winner of the committed study reproduction/studies/tuned-ic3net (decisions
    # 0215, 0245); tests/studies/test_published_presets.py checks these values against it.
    presets = {"tuned": Preset({"protocol": "mappo", "ppo_lr": 0.001, "entropy_coef": 0.01, "hidden": 64,
                                "comm_passes": 2, "gate": "open", "critic_hidden": 128, "optimizer": "adam"},
                               source="studies/definitions/ic3net.toml")}
    params: IC3NetParams

    def __init__(self, env, params=None, seed: int = 0, device=None) -> None:
        super().__init__(env, params, seed, device)
        p = self.params
        self.n_obs = local_view_size(p.patch_radius) + HISTORY_SIZE
        self.mappo = p.protocol == MAPPO  # the protocol's own critic replaces ``baseline``
        self.central = p.baseline == "central" or self.mappo
        self.policy = IC3NetPolicy(self.n_obs, p.hidden, p.comm_passes, p.action_path,
                                   p.patch_radius, value_head=not self.central)
        lr = p.ppo_lr if self.mappo else p.lr
        if p.optimizer == "adam":
            self.optimizer: torch.optim.Optimizer = torch.optim.Adam(self.policy.parameters(), lr=lr)
        else:
            self.optimizer = torch.optim.RMSprop(self.policy.parameters(), lr=lr,
                                                 alpha=p.rms_alpha, eps=p.rms_eps)
        self.critic: CentralCritic | RobotCritic | None = None
        if self.central:
            self.critic = RobotCritic(p.critic_hidden) if self.mappo else CentralCritic(p.critic_hidden)
        self.critic_opt = (torch.optim.Adam(self.critic.parameters(), lr=p.critic_lr)
                           if self.critic is not None else None)
        self.place_modules()

    # ------------------------------------------------------------ seed stacking
    # A stack view (OwnNetworksStack) runs the environment, observations, channel and links
    # on all S B episodes at once, and each seed's policy (encoder, communication, LSTM cell,
    # heads, value normalizer) its own B episodes with its own rows of the LSTM state.
    STACK_NET = "policy"

    def stack_state(self, state: IC3NetState, lo: int, hi: int) -> IC3NetState:
        """A stacked rollout's state for episodes lo..hi (its buffer already split): the
        LSTM states kept at chunk starts (mappo) of those episodes' robots only."""
        n = state.collided.shape[1]
        state.chunk_hc = [(h[lo * n:hi * n], c[lo * n:hi * n]) for h, c in state.chunk_hc]
        return state

    def rollout_policy(
        self, obs: torch.Tensor, mask: torch.Tensor, links: torch.Tensor, alive: torch.Tensor,
        hc: tuple[torch.Tensor, torch.Tensor],
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None, tuple[torch.Tensor, torch.Tensor]]:
        """The policy's rollout step (``IC3NetPolicy.forward``), with the per-robot values in
        return units (``value_norm``); a stack view's from each seed's policy on its own
        episodes and rows of ``hc`` (B N rows per seed, episode-major)."""
        if self._seeds is None:
            logits, gate_logits, values, hc = self.policy(obs, mask, links, alive, hc)
            if values is not None and self.params.value_norm:
                values = self.policy.value_norm.denormalize(values)
            return logits, gate_logits, values, hc
        n = obs.shape[1]
        outs: list[tuple[torch.Tensor, ...]] = []
        vals: list[torch.Tensor] = []
        for policy, lo, hi in self._seeds:
            logits, gate_logits, values, (h, c) = policy(
                obs[lo:hi], mask[lo:hi], links[lo:hi], alive[lo:hi], (hc[0][lo * n:hi * n], hc[1][lo * n:hi * n]))
            outs.append((logits, gate_logits, h, c))
            if values is not None:
                vals.append(policy.value_norm.denormalize(values) if self.params.value_norm else values)
        logits, gate_logits, h, c = (torch.cat(parts) for parts in zip(*outs, strict=True))
        return logits, gate_logits, torch.cat(vals) if vals else None, (h, c)

    def modules(self) -> dict[str, nn.Module | torch.optim.Optimizer]:
        mods: dict[str, nn.Module | torch.optim.Optimizer] = {"policy": self.policy, "optimizer": self.optimizer}
        if self.critic is not None and self.critic_opt is not None:  # set together (central)
            mods.update(critic=self.critic, critic_opt=self.critic_opt)
        return mods

    # ------------------------------------------------------------- controller
    def begin(self, batch: EpisodeBatch, choice: ActionChoice) -> IC3NetState:
        core, env, p = batch.core, self.env, self.params
        b, n = core.pos.shape
        loss = batch.open_channel("robots")
        buffer = None
        if choice.training:
            buffer = RolloutBuffer(env.horizon, b, {
                "obs": ((n, self.n_obs), np.float32), "mask": ((n, N_ACTIONS), bool),
                "links": ((n, n), bool), "alive": ((), np.int64), "active": ((n,), bool),
                "actions": ((n,), np.int64), "gates": ((n,), np.int64),
                **(critic_shapes(n) if self.central else {"values": ((n,), np.float32)}),
                **({"robot_reward": ((n,), np.float32), "logp": ((n,), np.float32)} if self.mappo else {}),
            })
        return IC3NetState(PatchExtractor(core, p.patch_radius), loss, buffer,
                           self.policy.initial_state(b, n), np.zeros((b, n), dtype=bool),
                           np.zeros((b, n), dtype=bool), ~core.ended)

    def links(self, state: IC3NetState, alive: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """(B, N_send, N_recv) bool: L_t = g^j g^i a^j a^i A_t[j, i], j != i (see module);
        written into ``out`` (e.g. the rollout buffer's row) when given."""
        delivered = state.loss.step()  # drawn every step, so the loss stream never shifts
        if out is None:
            out = np.empty_like(delivered)
        if not self.params.communicate:
            out[...] = False
            return out
        talk = state.gate & alive  # (B, N)
        np.logical_and(talk[:, :, None], talk[:, None, :], out=out)
        out &= delivered
        out &= _off_diagonal(talk.shape[1])
        return out

    def payload(self, state: IC3NetState, alive: np.ndarray) -> np.ndarray:
        """(B,) scalars sent: H per pass on each link with both gates open and both alive."""
        if not self.params.communicate:
            return np.zeros(alive.shape[0])
        k = (state.gate & alive).sum(axis=1).astype(np.float64)
        return k * (k - 1) * self.params.hidden * self.params.comm_passes

    def decide(self, batch: EpisodeBatch, state: IC3NetState, choice: ActionChoice) -> Decision:
        core, p, buf = batch.core, self.params, state.buffer
        b, n = core.pos.shape
        alive = ~core.done  # (B, N)
        # Training: inputs are written straight into the buffer's row (no concatenate, no copy).
        row = (lambda key: buf.row(key)) if buf is not None else (lambda key: None)
        links = self.links(state, alive, row("links"))
        payload = self.payload(state, alive)
        alive_n = alive.sum(axis=1)
        lv = local_view_size(p.patch_radius)
        obs = row("obs")
        if obs is None:
            obs = np.empty((b, n, self.n_obs), dtype=np.float32)
        local_view_into(core, state.patch, obs[..., :lv])
        own_history_into(core, state.collided, obs[..., lv:])
        mask = row("mask")
        if mask is None:
            mask = np.empty((b, n, N_ACTIONS), dtype=bool)
        action_mask_into(core, mask)
        if self.mappo and buf is not None and buf.t % p.detach_gap == 0:
            state.chunk_hc.append(state.hc)  # the mappo update replays chunks from here
        with torch.inference_mode():  # rollouts never backpropagate (the update replays)
            dev = self.device
            logits, gate_logits, values, state.hc = self.rollout_policy(
                torch.from_numpy(obs).to(dev), torch.from_numpy(mask).to(dev),
                torch.from_numpy(links.astype(np.float32)).to(dev), torch.from_numpy(alive_n).to(dev), state.hc)
            actions = choice(logits).numpy()
            gates = choice(gate_logits).numpy()  # the gate is an action too: same mode
            if buf is not None and "logp" in buf.data:  # mappo: the rollout policy's log-probs
                buf.row("logp")[...] = self.rollout_log_probs(logits, gate_logits, actions, gates).numpy()
        if p.gate != "learned":
            gates = np.full_like(gates, int(p.gate == "open"))
        state.gate = gates.astype(bool)
        state.running = ~core.ended
        if buf is not None:
            baseline = {}
            if self.central:
                store_critic_inputs(buf, core, self.env.horizon)
            else:  # the reference's V^i, in return units (rollout_policy)
                assert values is not None
                baseline = {"values": values.cpu().numpy()}
            buf.add(alive=alive_n, actions=actions, gates=gates, active=alive & state.running[:, None],
                    **baseline)
        return Decision(actions=actions, payload=payload, robot_links=links)

    def rollout_log_probs(self, logits: torch.Tensor, gate_logits: torch.Tensor, actions: np.ndarray,
                          gates: np.ndarray) -> torch.Tensor:
        """log pi of the sampled control, plus that of the sampled gate where the gate is
        learned (what the mappo update's ratio divides by; ic3net_mappo.py)."""
        logp = torch.log_softmax(logits, dim=-1).cpu().gather(-1, torch.from_numpy(actions)[..., None]).squeeze(-1)
        if self.params.gate == "learned" and self.params.communicate:
            logp = logp + torch.log_softmax(gate_logits, dim=-1).cpu().gather(
                -1, torch.from_numpy(gates)[..., None]).squeeze(-1)
        return logp

    def observe(self, batch: EpisodeBatch, state: IC3NetState, result: Any) -> None:
        state.collided = result.collision
        if state.buffer is not None:
            if self.mappo:
                state.buffer.add(robot_reward=robot_rewards(result))
            state.buffer.reward(result.reward, state.running)

    # ---------------------------------------------------------------- update
    def replay_step(
        self, data: dict[str, torch.Tensor], t: int, hc: tuple[torch.Tensor, torch.Tensor],
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, tuple[torch.Tensor, torch.Tensor]]:
        """The policy's step t again from the stored inputs (same outputs as the rollout)."""
        return self.policy(data["obs"][t], data["mask"][t], data["links"][t], data["alive"][t], hc)

    def per_robot_advantage(
        self, buf: RolloutBuffer, active: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The reference's baseline: A^i = G_t - V^i with the rollout's values (the
        parameters have not changed since), standardized over alive robot-steps with
        ``normalize_advantage``; and the value targets (T, B, N) (normalized with
        ``value_norm``, whose statistics this updates)."""
        p = self.params
        returns = mc_returns(buf.rewards[: buf.t])[..., None].to(self.device)  # (T, B, 1) team return G_t
        adv = returns - buf.tensor("values", self.device)
        if p.normalize_advantage:
            n_act = active.sum().clamp_min(1.0)
            mean = (adv * active).sum() / n_act
            std = torch.sqrt((((adv - mean) * active) ** 2).sum() / n_act).clamp_min(1e-6)
            adv = (adv - mean) / std
        targets = returns.expand_as(active)
        if p.value_norm:
            self.policy.value_norm.update(targets, active)
            targets = self.policy.value_norm.normalize(targets)
        return adv, targets

    def update(self, state: IC3NetState) -> dict[str, float]:
        """One critic step (``baseline="central"``) and one policy step: replay the batch
        with gradients, chunked over time (see module)."""
        buf, p = state.buffer, self.params
        assert buf is not None, "update() needs a training rollout"
        if isinstance(self.critic, RobotCritic):
            return mappo_update(self, state, self.critic)
        t_used = buf.t
        data = {k: buf.tensor(k, self.device) for k in buf.data}
        active = data["active"].float()  # (T, B, N) alive robots of running episodes
        n_steps = float(max(buf.running[:t_used].sum(), 1))  # environment steps in the batch
        n_active = float(active.sum().clamp_min(1.0))  # alive robot-steps
        out: dict[str, float] = {}
        crit: CriticStep | None = None
        if self.critic is not None and self.critic_opt is not None:  # the shared trainer: team advantage of V(X_t)
            crit = critic_update(self.critic, self.critic_opt, buf, p.normalize_advantage, p.max_grad_norm)
            adv = crit.adv[..., None].expand_as(active)  # (T, B, N): every robot, the team's A_t
            targets = None
            out["critic_loss"] = crit.loss
        else:
            adv, targets = self.per_robot_advantage(buf, active)
        b, n = data["actions"].shape[1:]
        hc = self.policy.initial_state(b, n)
        learn_gate = p.gate == "learned" and p.communicate
        self.optimizer.zero_grad()
        totals = dict(action_loss=0.0, value_loss=0.0, entropy=0.0)
        for lo in range(0, t_used, p.detach_gap):
            sl = slice(lo, min(lo + p.detach_gap, t_used))
            links = torch.from_numpy(buf.data["links"][sl].astype(np.float32)).to(self.device)  # once per chunk
            logits, gate_logits, values, hc = self.policy.replay(
                data["obs"][sl], data["mask"][sl], links, data["alive"][sl], hc)
            logp_all = torch.log_softmax(logits, dim=-1)
            logp = logp_all.gather(-1, data["actions"][sl][..., None]).squeeze(-1)
            if learn_gate:
                logp_g = torch.log_softmax(gate_logits, dim=-1)
                logp = logp + logp_g.gather(-1, data["gates"][sl][..., None]).squeeze(-1)
            m = active[sl]
            action_loss = -(adv[sl] * logp * m).sum()
            value_loss = torch.zeros(())
            if targets is not None and values is not None:  # both with a per-robot value head
                value_loss = (((values - targets[sl]) ** 2) * m).sum()
            entropy = -((logp_all.exp() * logp_all).sum(-1) * m).sum()
            loss = ((action_loss + p.value_coef * value_loss) / n_steps
                    - p.entropy_coef * entropy / n_active)
            loss.backward()
            hc = (hc[0].detach(), hc[1].detach())
            totals["action_loss"] += float(action_loss.detach()) / n_steps
            totals["value_loss"] += float(value_loss.detach()) / n_steps
            totals["entropy"] += float(entropy.detach())
        probe = self.kl_probe(data)
        grad_norm = clip_and_step(self.optimizer, p.max_grad_norm)
        diag = self.value_diagnostics(buf, active, crit)
        gate_open = float(buf.data["gates"][:t_used][buf.data["active"][:t_used]].mean()) \
            if buf.data["active"][:t_used].any() else 0.0
        running = torch.from_numpy(buf.running[:t_used].astype(np.float32))
        out.setdefault("critic_loss", totals["value_loss"])
        return {"actor_loss": totals["action_loss"], **out,
                "entropy": totals["entropy"] / n_active, "gate_open_rate": gate_open,
                "grad_norm": grad_norm,
                "return_mean": float((mc_returns(buf.rewards[:t_used]) * running).sum() / n_steps),
                **diag, "diag_entropy": totals["entropy"] / n_active, "diag_grad_norm": grad_norm,
                "diag_kl": probe.kl(),
                "diag_wait_share": wait_share(buf.data["actions"][:t_used], buf.data["active"][:t_used])}

    def value_diagnostics(self, buf: RolloutBuffer, active: torch.Tensor, crit: CriticStep | None,
                          ) -> dict[str, float]:
        """The baseline's ``diag_*`` numbers: the central critic's step, or the per-robot
        value head's values against the team return over alive robot-steps."""
        if crit is not None:
            return crit.diagnostics()
        returns = mc_returns(buf.rewards[: buf.t])[..., None].to(self.device).expand_as(active)
        return value_diagnostics(buf.tensor("values", self.device), returns, active)

    def kl_probe(self, data: dict[str, torch.Tensor]) -> KLProbe:
        """The action log-probabilities of the first ``detach_gap`` steps of up to two
        episodes, replayed from h = 0, for the KL across the step (diagnostics only)."""
        gap, eps = min(self.params.detach_gap, int(data["obs"].shape[0])), slice(0, 2)

        def log_probs() -> tuple[torch.Tensor, torch.Tensor]:
            obs = data["obs"][:gap, eps]
            links = data["links"][:gap, eps].to(torch.float32)
            hc = self.policy.initial_state(obs.shape[1], obs.shape[2])
            logits, _, _, _ = self.policy.replay(obs, data["mask"][:gap, eps], links, data["alive"][:gap, eps], hc)
            return torch.log_softmax(logits, dim=-1), data["active"][:gap, eps]

        return KLProbe(log_probs)
