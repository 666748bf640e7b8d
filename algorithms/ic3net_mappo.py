"""IC3Net's update under ``protocol="mappo"`` (algorithms/common/ppo.py; docs/decisions/0201).

The samples are (chunk, episode) pairs: the rollout keeps the LSTM state at the start of
every ``detach_gap``-step chunk (``IC3NetState.chunk_hc``), so a minibatch of pairs is
replayed in parallel for ``detach_gap`` steps from the stored states (the truncation of
the paper update, whose chunks start from the replayed state instead), one ratio per
alive robot-step for its control and (learned gate) its gate. The advantages are the
per-robot GAE advantages of the protocol's critic.
May import: algorithms.common (ppo, diagnostics, trainer), torch.
"""
from __future__ import annotations

from typing import Any

import torch
from torch.nn import functional as F

from algorithms.common.diagnostics import wait_share
from algorithms.common.ppo import PPOBatch, RobotCritic, mappo_critic, ppo_actor_update, update_generator

__all__ = ["mappo_update"]


def _chunked(x: torch.Tensor, gap: int) -> torch.Tensor:
    """(T, B, ...) -> (C, gap, B, ...) with the time axis zero-padded to C gap steps."""
    t = x.shape[0]
    c = -(-t // gap)
    pad = [0, 0] * (x.dim() - 1) + [0, c * gap - t]
    if x.dtype == torch.bool:  # F.pad has no bool kernel
        return F.pad(x.to(torch.uint8), pad).bool().reshape(c, gap, *x.shape[1:])
    return F.pad(x, pad).reshape(c, gap, *x.shape[1:])


def mappo_update(method: Any, state: Any, critic: RobotCritic) -> dict[str, float]:
    """One ``mappo`` update of IC3Net from a finished training batch: ``method`` is the
    ``IC3NetMethod`` and ``state`` its ``IC3NetState`` (typed loosely: naming them here would
    close an import circle with algorithms/ic3net.py)."""
    p, buf = method.params, state.buffer
    assert buf is not None and method.critic_opt is not None
    gen = update_generator(method.seed, method.iterations)
    crit = mappo_critic(critic, method.critic_opt, buf, p, gen=gen)
    gap = p.detach_gap
    dev = method.device
    data = {k: _chunked(buf.tensor(k, dev), gap) for k in ("obs", "mask", "links", "alive", "actions", "gates")}
    active = _chunked(buf.tensor("active", dev), gap).to(torch.float32)  # (C, gap, B, N)
    adv = _chunked(crit.robot_adv, gap)
    c, _, b, n = active.shape
    h0 = torch.stack([hc[0].clone() for hc in state.chunk_hc[:c]]).view(c, b, n, -1)  # (C, B, N, H)
    c0 = torch.stack([hc[1].clone() for hc in state.chunk_hc[:c]]).view(c, b, n, -1)
    learn_gate = p.gate == "learned" and p.communicate
    pairs_c = torch.arange(c).repeat_interleave(b)  # sample k = (chunk, episode)
    pairs_b = torch.arange(b).repeat(c)

    def pick(x: torch.Tensor, ci: torch.Tensor, bi: torch.Tensor) -> torch.Tensor:  # (C, gap, B, ...) -> (gap, K, ...)
        return x[ci, :, bi].transpose(0, 1)

    def per_sample(x: torch.Tensor) -> torch.Tensor:  # (gap, K, N) -> (K, gap N)
        return x.transpose(0, 1).reshape(x.shape[1], -1)

    def log_probs(ix: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        ci, bi = pairs_c[ix], pairs_b[ix]
        k = len(ix)
        hc = (h0[ci, bi].reshape(k * n, -1), c0[ci, bi].reshape(k * n, -1))
        logits, gate_logits, _, _ = method.policy.replay(
            pick(data["obs"], ci, bi), pick(data["mask"], ci, bi), pick(data["links"], ci, bi).to(torch.float32),
            pick(data["alive"], ci, bi), hc)
        logp_all = torch.log_softmax(logits, dim=-1)
        logp = logp_all.gather(-1, pick(data["actions"], ci, bi)[..., None]).squeeze(-1)
        if learn_gate:
            logp = logp + torch.log_softmax(gate_logits, dim=-1).gather(
                -1, pick(data["gates"], ci, bi)[..., None]).squeeze(-1)
        entropy = -(logp_all.exp() * logp_all).sum(-1)
        return per_sample(logp), per_sample(entropy), per_sample(pick(active, ci, bi))

    advantages = per_sample(pick(adv, pairs_c, pairs_b))
    old = per_sample(pick(_chunked(buf.tensor("logp", dev), gap), pairs_c, pairs_b))  # the rollout's, kept
    out = ppo_actor_update(PPOBatch(c * b, log_probs, advantages, old_log_probs=old), method.optimizer, p.ppo_epochs,
                           p.ppo_minibatches, p.ppo_clip, p.entropy_coef, p.max_grad_norm, gen)
    t_used = buf.t
    act = buf.data["active"][:t_used]
    return {**crit.losses, **out, "grad_norm": out["diag_grad_norm"], "entropy": out["diag_entropy"],
            "gate_open_rate": float(buf.data["gates"][:t_used][act].mean()) if act.any() else 0.0,
            "diag_wait_share": wait_share(buf.data["actions"][:t_used], act)}
