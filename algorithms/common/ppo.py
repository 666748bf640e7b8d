"""The ``mappo`` training protocol: the field's standard actor-critic, open to every learned method.

``protocol = "paper"`` (the default) is the paper's trainer (trainer.py), bit for bit.
``protocol = "mappo"`` (MAPPO, Yu et al. 2022; CleanRL's ppo.py) trains the same policies
on the same rollouts with (docs/decisions/0201):

* ``RobotCritic``: a centralized critic on the same global state X_t (and t / T) that
  predicts, per robot, the value of that robot's own reward terms (progress, goal,
  collision, time; the environment's ``StepResult`` reports them). The team reward is their
  mean, so the team value is the mean of the robots' values: one critic serves per-robot
  credit and team credit. It predicts ``ValueNorm``-normalized returns.
* ``gae``: GAE(lambda) with discount ``gamma`` on per-robot (``credit="robot"``), per-group
  (the hierarchical reference) or team rewards, terminal at the episode's end.
* ``fit_critic``: ``ppo_epochs`` x ``ppo_minibatches`` Adam steps on the normalized
  per-robot returns, on the actor's minibatch count (docs/decisions/0220).
* ``ppo_actor_update``: the clipped surrogate over ``ppo_epochs`` epochs of
  ``ppo_minibatches`` shuffled minibatches, advantages normalized per minibatch (mean and
  std; each level apart where a method's ratios come from policies at different scales,
  ``PPOBatch.levels``), an entropy bonus, the global gradient-norm clip; the old log-probabilities are the
  rollout policy's, recomputed once before the first step.

A method (a plugin too, docs/training-protocols.md) supplies only what is its own: which
rows it learns from and how to compute their log-probabilities (``PPOBatch``).
May import: envs, algorithms.common (trainer, value_norm, diagnostics, device, precision).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import torch
from torch import nn

from algorithms.common.device import module_device
from algorithms.common.diagnostics import value_diagnostics
from algorithms.common.precision import autocast, to_fp32
from algorithms.common.trainer import CRITIC_FEATURES, RolloutBuffer, clip_and_step
from algorithms.common.value_norm import ValueNorm

__all__ = ["MAPPO", "PAPER", "MAPPOCritic", "PPOBatch", "RobotCritic", "fit_critic", "gae", "mappo_critic",
           "ppo_actor_update", "robot_rewards", "update_generator"]

PAPER, MAPPO = "paper", "mappo"


class MAPPOParams(Protocol):
    """The ``LearnedParams`` fields the protocol reads (algorithms/base.py)."""

    @property
    def gamma(self) -> float: ...
    @property
    def gae_lambda(self) -> float: ...
    @property
    def credit(self) -> str: ...
    @property
    def ppo_epochs(self) -> int: ...
    @property
    def ppo_minibatches(self) -> int: ...
    @property
    def max_grad_norm(self) -> float: ...


def robot_rewards(result: object) -> np.ndarray:
    """(B, N) float32 per-robot reward terms of a step; the team reward is their mean."""
    r = result  # envs.core.StepResult
    terms = r.progress + r.goal_bonus + r.collision_penalty + r.time_penalty  # type: ignore[attr-defined]
    return np.asarray(terms, dtype=np.float32)


class RobotCritic(nn.Module):
    """V_i(X_t) for every robot i: DeepSets over the robots' global features; each robot's
    value from its embedding, the mean embedding, t / T and the share of robots done.

    The first head layer acts on [e_i, context] as one linear map split in two: the
    embedding part per robot, the context part once per step (the same function as a
    linear layer on the concatenation, at a fraction of the cost)."""

    def __init__(self, hidden: int) -> None:
        super().__init__()
        self.phi = nn.Sequential(nn.Linear(CRITIC_FEATURES, hidden), nn.ReLU(),
                                 nn.Linear(hidden, hidden), nn.ReLU())
        self.head_robot = nn.Linear(hidden, hidden)
        self.head_context = nn.Linear(hidden + 2, hidden, bias=False)
        self.out = nn.Linear(hidden, 1)
        self.value_norm = ValueNorm()

    def forward(self, robots: torch.Tensor, t_frac: torch.Tensor) -> torch.Tensor:
        """robots (..., N, 6), t_frac (...) -> normalized values (..., N)."""
        e = self.phi(robots)
        ctx = torch.cat([e.mean(dim=-2), t_frac[..., None], robots[..., 5].mean(dim=-1, keepdim=True)], dim=-1)
        x = torch.relu(self.head_robot(e) + self.head_context(ctx)[..., None, :])
        return self.out(x).squeeze(-1)


def gae(rewards: torch.Tensor, values: torch.Tensor, running: torch.Tensor, gamma: float, lam: float,
        ) -> tuple[torch.Tensor, torch.Tensor]:
    """GAE(lambda): rewards and values (T, B, K) (K robots, groups or 1), running (T, B) bool.

    The value after the last running step of an episode is 0 (the paper's episodes end at
    the horizon T, which the critic sees as t / T, or when every robot is done). Returns the
    advantages and the value targets A + V, (T, B, K), zero after the episode ended."""
    t_len = rewards.shape[0]
    run = running.to(torch.float32)[..., None]
    adv = torch.zeros_like(rewards)
    last = torch.zeros_like(rewards[0])
    for t in reversed(range(t_len)):
        nxt = run[t + 1] if t + 1 < t_len else torch.zeros_like(run[0])
        v_next = values[t + 1] * nxt if t + 1 < t_len else torch.zeros_like(values[0])
        delta = rewards[t] + gamma * v_next - values[t]
        last = (delta + gamma * lam * nxt * last) * run[t]
        adv[t] = last
    return adv, (adv + values) * run


def fit_critic(critic: RobotCritic, optimizer: torch.optim.Optimizer, states: torch.Tensor, t_frac: torch.Tensor,
               targets_of: Callable[[torch.Tensor], torch.Tensor], running: torch.Tensor, epochs: int,
               max_grad_norm: float, minibatches: int = 1, gen: torch.Generator | None = None,
               ) -> tuple[torch.Tensor, torch.Tensor, dict[str, float]]:
    """``epochs`` x ``minibatches`` Adam steps of the critic on per-robot value targets over
    the running steps, in ValueNorm units (MAPPO fits the critic on the actor's minibatches:
    as many steps as the actor at the cost of one full pass per epoch). The values before
    any step come from one forward pass (denormalized, no gradient); ``targets_of(values)``
    turns them into the targets (T, B, N), which update the ValueNorm statistics before the
    first step. The minibatches are (t, b) steps shuffled by ``gen`` (``None`` with one
    minibatch: the whole batch, in order). Returns the values, the targets, and the last
    loss and gradient norm. The critic's forward passes run under the critic's precision
    (precision.py), their outputs float32 before the ValueNorm and the loss."""
    def forward(s: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        with autocast(critic):
            return to_fp32(critic(s, t))

    with torch.no_grad():
        values = critic.value_norm.denormalize(forward(states, t_frac))
    targets = targets_of(values)
    mask = running.to(torch.float32)[..., None].expand_as(targets)
    critic.value_norm.update(targets, mask)
    norm_targets = critic.value_norm.normalize(targets)
    rows = running.numel()
    flat_states, flat_t = states.reshape(rows, *states.shape[2:]), t_frac.reshape(rows)
    flat_targets, flat_mask = norm_targets.reshape(rows, -1), mask.reshape(rows, -1)
    loss, grad_norm = torch.zeros(()), float("nan")
    for _ in range(epochs):
        order = torch.arange(rows) if gen is None else torch.randperm(rows, generator=gen)
        for ix in order.chunk(max(1, minibatches)):
            m = flat_mask[ix]
            pred = forward(flat_states[ix], flat_t[ix])
            loss = (((pred - flat_targets[ix]) ** 2) * m).sum() / m.sum().clamp_min(1.0)
            optimizer.zero_grad()
            loss.backward()
            grad_norm = clip_and_step(optimizer, max_grad_norm)
    return values, targets, {"critic_loss": float(loss.detach()), "diag_critic_grad_norm": grad_norm}


def critic_diagnostics(values: torch.Tensor, targets: torch.Tensor, running: torch.Tensor) -> dict[str, float]:
    """``diag_*`` of the critic on the team scale: mean over robots of values and targets."""
    return value_diagnostics(values.mean(-1), targets.mean(-1), running.to(torch.float32))


@dataclass
class PPOBatch:
    """What a method hands ``ppo_actor_update``: ``rows`` samples (robot-steps, group-steps,
    episodes...), and ``log_probs(index)`` -> (log-probabilities (K, S), entropies (K, S),
    weights (K, S)) of the index's samples under the current parameters, S ratios per sample
    (1 for a robot's action; a method may give several, e.g. the reference and the robots of
    a group-step), weights 1 where a ratio counts. ``advantages`` (rows, S) per ratio.

    ``levels`` (S,) optional: the level of each ratio column (0, 1, ...) where the columns
    hold policies whose advantages differ in scale (a group's summed return beside a robot's);
    each level's advantages are normalized on their own and its entropy and KL reported
    under ``level_names`` (``""``: ``diag_entropy``, ``diag_kl``; ``"ref"``:
    ``diag_entropy_ref``, ``diag_kl_ref``). Without it every column is one level.

    ``old_log_probs`` (rows, S) optional: the rollout policy's log-probabilities, kept by the
    rollout (MAPPO's stored action log-probs); without them ``ppo_actor_update`` recomputes
    them with one forward pass before its first step."""

    rows: int
    log_probs: Callable[[torch.Tensor], tuple[torch.Tensor, torch.Tensor, torch.Tensor]]
    advantages: torch.Tensor
    levels: torch.Tensor | None = None
    level_names: tuple[str, ...] = ("",)
    old_log_probs: torch.Tensor | None = None


def update_generator(seed: int, iteration: int) -> torch.Generator:
    """The minibatch shuffling stream of one update (no draw from the training streams)."""
    return torch.Generator().manual_seed(int(np.random.SeedSequence([seed, 54, iteration]).generate_state(1)[0]))


def _normalized(adv: torch.Tensor, w: torch.Tensor, onehot: torch.Tensor) -> torch.Tensor:
    """Advantages (K, S) normalized to mean 0 and std 1 over the counted ratios (w > 0) of
    each level; ``onehot`` (S, L) maps columns to levels."""
    n = (w.sum(0) @ onehot).clamp_min(1.0)  # (L,)
    mean = ((adv * w).sum(0) @ onehot) / n
    centred = adv - mean @ onehot.T
    std = torch.sqrt((((centred * w) ** 2).sum(0) @ onehot) / n).clamp_min(1e-6)
    return centred / (std @ onehot.T)


def ppo_actor_update(batch: PPOBatch, optimizer: torch.optim.Optimizer, epochs: int, minibatches: int,
                     clip: float, entropy_coef: float, max_grad_norm: float, gen: torch.Generator,
                     ) -> dict[str, float]:
    """The clipped surrogate -min(rho A, clip(rho, 1 -+ eps) A) - c H over ``epochs`` x
    ``minibatches`` Adam steps; A normalized per minibatch over the counted ratios of each
    level (``PPOBatch.levels``). Returns the mean actor loss, per level the mean entropy and
    the approximate KL (mean of (rho - 1) - log rho over the last epoch), the clip fraction
    and the last gradient norm. ``batch.log_probs`` runs under the precision of
    ``optimizer`` (its policy's; precision.py), its outputs float32 before the loss."""
    def log_probs(ix: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        with autocast(optimizer):
            logp, ent, w = batch.log_probs(ix)
        return to_fp32(logp), to_fp32(ent), to_fp32(w)

    cols = batch.advantages.shape[1]
    levels = torch.zeros(cols, dtype=torch.long) if batch.levels is None else batch.levels
    dev = batch.advantages.device
    onehot = torch.nn.functional.one_hot(levels, len(batch.level_names)).to(dev, torch.float32)  # (S, L)
    old = batch.old_log_probs
    if old is None:
        with torch.no_grad():  # the rollout policy (parameters unchanged since the rollout)
            old = torch.cat([log_probs(ix)[0] for ix in torch.arange(batch.rows).split(16384)])
    loss_sum, steps, grad_norm = 0.0, 0, float("nan")
    ent_sum = torch.zeros(len(batch.level_names), device=dev)
    ent_steps = torch.zeros(len(batch.level_names), device=dev)
    kl_sum, counted = torch.zeros(len(batch.level_names), device=dev), torch.zeros(len(batch.level_names), device=dev)
    clipped = 0.0
    for epoch in range(epochs):
        perm = torch.randperm(batch.rows, generator=gen)
        for ix in perm.chunk(max(1, minibatches)):
            logp, ent, w = log_probs(ix)
            adv = _normalized(batch.advantages[ix], w, onehot)
            n = w.sum().clamp_min(1.0)
            log_ratio = logp - old[ix]
            ratio = log_ratio.exp()
            surrogate = torch.minimum(ratio * adv, ratio.clamp(1 - clip, 1 + clip) * adv)
            loss = -(surrogate * w).sum() / n - entropy_coef * (ent * w).sum() / n
            optimizer.zero_grad()
            loss.backward()
            grad_norm = clip_and_step(optimizer, max_grad_norm)
            steps += 1
            loss_sum += float(loss.detach())
            with torch.no_grad():
                level_n = w.sum(0) @ onehot  # counted ratios per level in this minibatch
                ent_sum += ((ent * w).sum(0) @ onehot) / level_n.clamp_min(1.0)
                ent_steps += (level_n > 0).float()
                if epoch == epochs - 1:
                    kl_sum += (((ratio - 1) - log_ratio) * w).sum(0) @ onehot
                    clipped += float((((ratio - 1).abs() > clip).float() * w).sum())
                    counted += w.sum(0) @ onehot
    out = {"actor_loss": loss_sum / max(steps, 1), "clip_fraction": clipped / max(float(counted.sum()), 1.0),
           "diag_grad_norm": grad_norm}
    for i, name in enumerate(batch.level_names):
        suffix = f"_{name}" if name else ""
        out[f"diag_entropy{suffix}"] = float(ent_sum[i]) / max(float(ent_steps[i]), 1.0)
        out[f"diag_kl{suffix}"] = float(kl_sum[i]) / max(float(counted[i]), 1.0)
    return out


@dataclass
class MAPPOCritic:
    """What ``mappo_critic`` gives the actor update: advantages per robot (T, B, N) under
    the method's ``credit`` (the team's advantage repeated for every robot with
    ``credit="team"``), the per-robot values and GAE inputs, and the row values."""

    robot_adv: torch.Tensor
    values: torch.Tensor  # (T, B, N) denormalized, before the critic's steps
    rewards: torch.Tensor  # (T, B, N) per-robot reward terms
    running: torch.Tensor  # (T, B) bool
    losses: dict[str, float]


def mappo_critic(critic: RobotCritic, optimizer: torch.optim.Optimizer, buf: RolloutBuffer,
                 p: MAPPOParams, t_frac: torch.Tensor | None = None, gen: torch.Generator | None = None,
                 ) -> MAPPOCritic:
    """The critic half of a ``mappo`` update on a rollout buffer holding ``critic``,
    ``t_frac`` (``critic_inputs``) and ``robot_reward`` (T, B, N): values before the step,
    GAE advantages and targets, then ``fit_critic``. ``t_frac`` (T, B): t / T where the
    buffer does not store it. ``gen`` (``update_generator``) shuffles the critic's
    ``ppo_minibatches`` minibatches; without it the critic takes one full-batch step per
    epoch."""
    dev = module_device(critic)
    states = buf.tensor("critic", dev)
    t_frac = buf.tensor("t_frac", dev) if t_frac is None else t_frac
    rewards = buf.tensor("robot_reward", dev)
    running = torch.from_numpy(buf.running[: buf.t]).to(dev)
    adv = torch.zeros(())

    def targets_of(values: torch.Tensor) -> torch.Tensor:
        nonlocal adv
        adv, targets = gae(rewards, values, running, p.gamma, p.gae_lambda)
        if p.credit == "team":
            team_adv, _ = gae(rewards.mean(-1, keepdim=True), values.mean(-1, keepdim=True), running,
                              p.gamma, p.gae_lambda)
            adv = team_adv.expand_as(adv)
        return targets

    values, targets, fit = fit_critic(critic, optimizer, states, t_frac, targets_of, running, p.ppo_epochs,
                                      p.max_grad_norm, p.ppo_minibatches if gen is not None else 1, gen)
    losses = {**critic_diagnostics(values, targets, running), **fit}
    return MAPPOCritic(adv, values, rewards, running, losses)
