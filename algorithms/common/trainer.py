"""The paper's trainer, shared by every learned method (eq:training_return..eq:losses).

* ``mc_returns``: undiscounted Monte-Carlo return G_t = sum_{k>=t} R_k (eq:training_return).
* ``CentralCritic``: V_omega(X_t) on the global state, a DeepSets network over robots so
  one architecture serves any N (mean-pooled per-robot embeddings + episode progress).
* ``RolloutBuffer``: preallocated (T, B, ...) arrays; memory is bounded by one batch,
  never by the number of episodes trained.
* ``team_advantage``: the team advantage A_t = G_t - V(X_t) (eq:advantage) shared by
  every actor, optionally divided by its batch RMS (the same normalization for every
  method); ``policy_gradient_losses``: the actor loss -A log pi and the critic loss
  (V - G)^2 (eq:losses) built on it.
* ``critic_loss``, ``clip_and_step``, ``critic_step`` / ``critic_update``: the one critic
  update of every learned method (masked squared return error, global gradient-norm clip, Adam step;
  Algorithm 2 line "Update centralized critic V_omega"). The actors use ``clip_and_step``
  too, so every learned method clips its gradients alike (``max_grad_norm``).
* ``critic_inputs`` / ``critic_shapes``: what a rollout stores for the critic, X_t and t/T.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from numpy.typing import DTypeLike
from torch import nn

from algorithms.common.device import module_device
from algorithms.common.diagnostics import value_diagnostics
from algorithms.common.precision import autocast, to_fp32
from envs.core import WarehouseCore

CRITIC_FEATURES = 6


def mc_returns(rewards: np.ndarray | torch.Tensor) -> torch.Tensor:
    """(T, B) rewards -> (T, B) returns G_t = sum_{k=t}^{T-1} R_k (eq:training_return)."""
    r = torch.as_tensor(rewards, dtype=torch.float32)
    return torch.flip(torch.cumsum(torch.flip(r, dims=[0]), dim=0), dims=[0])


def critic_features(core: WarehouseCore, out: np.ndarray | None = None) -> np.ndarray:
    """(B, N, 6) float32 global state X_t per robot (eq:advantage, V_omega(X_t)):
    [row/H, col/W, goal row/H, goal col/W, min(D(p, g), H W)/(H+W), done];
    written into ``out`` (a (B, N, 6) float32 view, e.g. a buffer row) when given."""
    h, w = core.layout.shape
    scale = np.array([h, w], dtype=np.float32)
    if out is None:
        out = np.empty(core.pos.shape + (CRITIC_FEATURES,), dtype=np.float32)
    np.divide(np.take(core.layout.cells, core.pos, axis=0).astype(np.float32), scale, out=out[..., 0:2])
    np.divide(np.take(core.layout.cells, core.goal, axis=0).astype(np.float32), scale, out=out[..., 2:4])
    out[..., 4] = (np.minimum(core.dist, h * w) / float(h + w)).astype(np.float32)
    out[..., 5] = core.done
    return out


def critic_shapes(n: int) -> dict[str, tuple[tuple[int, ...], DTypeLike]]:
    """``RolloutBuffer`` fields of the critic's inputs for N robots (see ``critic_inputs``)."""
    return {"critic": ((n, CRITIC_FEATURES), np.float32), "t_frac": ((), np.float32)}


def critic_inputs(core: WarehouseCore, horizon: int) -> dict[str, np.ndarray]:
    """The critic's inputs at the current step: X_t (B, N, 6) and t / T (B,), float32."""
    return {"critic": critic_features(core),
            "t_frac": np.full(core.batch, core.t / horizon, dtype=np.float32)}


def store_critic_inputs(buffer: RolloutBuffer, core: WarehouseCore, horizon: int) -> None:
    """``critic_inputs`` written straight into the buffer's current row (no copies)."""
    critic_features(core, buffer.row("critic"))
    buffer.row("t_frac")[...] = np.float32(core.t / horizon)


class CentralCritic(nn.Module):
    """V_omega(X_t): DeepSets over the robots' global features plus time t / T."""

    def __init__(self, hidden: int) -> None:
        super().__init__()
        self.phi = nn.Sequential(nn.Linear(CRITIC_FEATURES, hidden), nn.ReLU(),
                                 nn.Linear(hidden, hidden), nn.ReLU())
        self.rho = nn.Sequential(nn.Linear(hidden + 2, hidden), nn.ReLU(), nn.Linear(hidden, 1))

    def forward(self, robots: torch.Tensor, t_frac: torch.Tensor) -> torch.Tensor:
        """robots (..., N, 6), t_frac (...) -> V (...)."""
        # sum / N is torch's CPU mean (sum, then divide), bit for bit; its backward divides
        # the (..., H) gradient before expanding it over the robots instead of after.
        pooled = self.phi(robots).sum(dim=-2) / robots.shape[-2]
        done_frac = robots[..., 5].mean(dim=-1, keepdim=True)
        return self.rho(torch.cat([pooled, t_frac[..., None], done_frac], dim=-1)).squeeze(-1)


class RolloutBuffer:
    """Named, preallocated (T, B, ...) arrays filled step by step during a rollout."""

    def __init__(self, horizon: int, batch: int, shapes: dict[str, tuple[tuple[int, ...], DTypeLike]]):
        self.data = {k: np.zeros((horizon, batch, *shape), dtype=dt) for k, (shape, dt) in shapes.items()}
        self.rewards = np.zeros((horizon, batch), dtype=np.float32)
        self.running = np.zeros((horizon, batch), dtype=bool)
        self.t = 0

    def add(self, **fields: np.ndarray) -> None:
        for key, val in fields.items():
            self.data[key][self.t] = val

    def row(self, key: str) -> np.ndarray:
        """The current step's slot of a field, (B, ...), to be written in place (instead
        of ``add``) before ``reward`` advances the step."""
        return self.data[key][self.t]

    def reward(self, reward: np.ndarray, running: np.ndarray) -> None:
        self.rewards[self.t] = reward
        self.running[self.t] = running
        self.t += 1

    def tensor(self, key: str, device: torch.device | str = "cpu") -> torch.Tensor:
        """The first ``t`` steps of a field as a tensor (T_used, B, ...) on ``device`` (the
        storage is the host's: the environment writes into it in place)."""
        return torch.from_numpy(self.data[key][: self.t]).to(device)


@dataclass
class PGLosses:
    actor: torch.Tensor
    critic: torch.Tensor
    advantage_mean: float
    return_mean: float


def policy_gradient_losses(
    logp: torch.Tensor, values: torch.Tensor, rewards: np.ndarray, running: np.ndarray,
    normalize: bool = True,
) -> PGLosses:
    """Team-advantage actor and critic losses (eq:advantage, eq:losses).

    logp (T, B): summed log-probabilities of everything sampled at step t (every group's
    reference and joint control, or every robot's action); values (T, B): V(X_t);
    rewards, running (T, B). Steps after an episode ended are masked out. With
    ``normalize`` the advantage is scaled by its batch standard deviation (a constant
    factor per batch; see docs/decisions/0113).
    """
    adv, g, mask, n = team_advantage(values, rewards, running, normalize)
    actor = -(adv * logp * mask).sum() / n
    critic = critic_loss(values, g, mask, n)
    return PGLosses(actor, critic, float((adv * mask).sum() / n), float((g * mask).sum() / n))


def team_advantage(
    values: torch.Tensor, rewards: np.ndarray, running: np.ndarray, normalize: bool = True,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Detached team advantage A_t = G_t - V(X_t) (eq:advantage) and what weighs it.

    values, rewards, running (T, B) -> (adv, G, mask, n): adv and G (T, B), mask (T, B)
    float of running steps, n = number of running steps (>= 1). With ``normalize`` adv is
    divided by its batch root-mean-square. ``policy_gradient_losses`` is built on it;
    methods whose actor loss is too large for one backward pass (chunked over time) use it
    directly and weight each chunk's log-probabilities with the same adv / n.
    """
    g = mc_returns(rewards).to(values.device)
    mask = torch.as_tensor(running, dtype=torch.float32, device=values.device)
    n = mask.sum().clamp_min(1.0)
    adv = (g - values).detach()
    if normalize:
        std = torch.sqrt(((adv * mask) ** 2).sum() / n).clamp_min(1e-6)
        adv = adv / std
    return adv, g, mask, n


def critic_loss(
    values: torch.Tensor, returns: torch.Tensor, mask: torch.Tensor | float, n: torch.Tensor | float,
) -> torch.Tensor:
    """L_V (eq:losses): sum over running steps of (V(X_t) - G_t)^2, divided by n.

    values, returns (...) alike; mask (...) 1 for running steps, 0 after an episode ended
    (or 1.0 when every row is a running step); n the number of running steps of the batch.
    """
    return (((values - returns) ** 2) * mask).sum() / n


def clip_and_step(optimizer: torch.optim.Optimizer, max_grad_norm: float) -> float:
    """Clip the global gradient norm of ``optimizer``'s parameters at ``max_grad_norm``,
    step, and return the norm before clipping. Every learned method's actor and critic
    steps go through here, so they clip alike."""
    params = [q for group in optimizer.param_groups for q in group["params"]]
    norm = nn.utils.clip_grad_norm_(params, max_grad_norm)
    optimizer.step()
    return float(norm)


@dataclass
class CriticStep:
    """What ``critic_step`` gives the actor update: the detached values V(X_t) before the
    step, team advantage adv and returns G (T, B), the running mask (T, B), n running
    steps, the critic loss."""

    values: torch.Tensor
    adv: torch.Tensor
    returns: torch.Tensor
    mask: torch.Tensor
    n: torch.Tensor
    loss: float
    grad_norm: float = float("nan")  # the critic's gradient norm before clipping

    def diagnostics(self) -> dict[str, float]:
        """The ``diag_*`` numbers of the critic step (algorithms/common/diagnostics.py):
        raw advantage and return moments, explained variance, gradient norm."""
        return {**value_diagnostics(self.values, self.returns, self.mask),
                "diag_critic_grad_norm": self.grad_norm}


def critic_step(
    critic: CentralCritic, optimizer: torch.optim.Optimizer, states: torch.Tensor, t_frac: torch.Tensor,
    rewards: np.ndarray, running: np.ndarray, normalize: bool, max_grad_norm: float,
) -> CriticStep:
    """One step of V_omega on a finished batch, and the team advantage for the actors.

    states (T, B, N, 6) X_t, t_frac (T, B), rewards and running (T, B). One forward over
    the whole batch: A_t = G_t - V(X_t) is computed with these values, before the step
    (eq:advantage; detached, so the actor loss never trains the critic), and
    L_V = sum (V - G)^2 / n over running steps (eq:losses) is minimized by one clipped
    optimizer step (Algorithm 2: "Update centralized critic V_omega"). Every learned
    method's critic is stepped here. With ``precision = "bf16"`` the forward pass runs under
    autocast and the values come back as float32 before the loss (precision.py).
    """
    with autocast(critic):
        values = to_fp32(critic(states, t_frac))  # (T, B)
    adv, g, mask, n = team_advantage(values, rewards, running, normalize)
    loss = critic_loss(values, g, mask, n)
    optimizer.zero_grad()
    loss.backward()
    grad_norm = clip_and_step(optimizer, max_grad_norm)
    return CriticStep(values.detach(), adv, g, mask, n, float(loss.detach()), grad_norm)


def critic_update(
    critic: CentralCritic, optimizer: torch.optim.Optimizer, buf: RolloutBuffer,
    normalize: bool, max_grad_norm: float,
) -> CriticStep:
    """``critic_step`` on a rollout buffer that stored ``critic`` (T, B, N, 6) and
    ``t_frac`` (T, B) with ``critic_inputs``."""
    dev = module_device(critic)
    return critic_step(critic, optimizer, buf.tensor("critic", dev), buf.tensor("t_frac", dev),
                       buf.rewards[: buf.t], buf.running[: buf.t], normalize, max_grad_norm)
