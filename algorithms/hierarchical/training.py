"""The updates of the hierarchical method from one finished rollout batch.

* ``policy_update`` (eq:training_return, eq:advantage, eq:losses): the centralized critic
  V_omega(X_t) is stepped and gives the team advantage A_t = G_t - V(X_t) (shared trainer,
  ``critic_step``, as every learned method); the same A_t weighs log mu(r_t^z | o_t^z) + log pi(U~_t^z | w_t^z)
  of every group (the policy gradient is on the sampled policy outputs, the filter is part
  of the transition). Rows are the running (t, b) steps, processed in time chunks, each
  with its own backward pass (the losses are sums, so the gradient is the full-batch one).
  An entropy bonus on both levels is optional (``entropy_coef``; not in the paper).
* ``predictor_update`` (eq:gru_pred_loss): the GRU predictors are unrolled over the whole
  episode from the stored true messages and availabilities; the squared error of the
  predicted messages on lost links only is minimized with its own Adam optimizer.
  The encoder and the decoder run in time chunks; no activation checkpointing: the
  recomputation made the update 1.7x slower and did not lower the process's peak memory,
  which the policy update sets (measured at N = 100, horizon 500; docs/decisions/0104).

Both take a ``Learner``: the networks, optimizers, group structure and hyperparameters the
method hands over (``HierarchicalMethod.learner``), so this module never imports the method.
May import: algorithms.common, algorithms.hierarchical (params, messages, policies, predictor), envs.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from algorithms.common.device import module_device
from algorithms.common.diagnostics import KLProbe, probe_rows, wait_share
from algorithms.common.ppo import RobotCritic
from algorithms.common.precision import autocast, to_fp32
from algorithms.common.trainer import (
    CentralCritic,
    RolloutBuffer,
    clip_and_step,
    critic_step,
    mc_returns,
)
from algorithms.hierarchical.messages import GroupStructure
from algorithms.hierarchical.params import HierarchicalParams
from algorithms.hierarchical.policies import (
    LocalPolicy,
    ReferencePolicy,
    group_major,
    policy_forward,
)
from algorithms.hierarchical.predictor import GroupPredictor, predictor_loss
from envs.actions import WAIT


@dataclass(frozen=True)
class Learner:
    """What the updates read and step: the method's networks and optimizers (the same
    objects, updated in place), its group structure, hyperparameters and episode sizes."""

    params: HierarchicalParams
    gs: GroupStructure
    horizon: int  # T of the environment (the critic's time feature t / T)
    n_robots: int  # N
    reference: ReferencePolicy
    local: LocalPolicy
    predictor: GroupPredictor
    critic: CentralCritic | RobotCritic  # RobotCritic under protocol="mappo" (mappo.py)
    opt_policy: torch.optim.Optimizer
    opt_critic: torch.optim.Optimizer
    opt_predictor: torch.optim.Optimizer

    @property
    def device(self) -> torch.device:
        """The networks' device: tensors built from the buffer go there."""
        return module_device(self.critic)


def _entropy(logp: torch.Tensor) -> torch.Tensor:
    return -(logp.exp() * logp).sum(-1)


def policy_update(learner: Learner, buf: RolloutBuffer) -> dict[str, float]:
    """One Adam step of mu, pi (team advantage) and V_omega (squared return error)."""
    p = learner.params
    t_used = buf.t
    d = {k: v[:t_used] for k, v in buf.data.items()}
    running, rewards = buf.running[:t_used], buf.rewards[:t_used]
    dev = learner.device
    t_frac = torch.from_numpy(
        np.broadcast_to((np.arange(t_used, dtype=np.float32) / learner.horizon)[:, None], running.shape).copy()).to(dev)
    assert isinstance(learner.critic, CentralCritic)  # the paper protocol's critic
    # The critic first (its own parameters and optimizer): one step on the whole batch,
    # and the team advantage from its values before the step.
    crit = critic_step(learner.critic, learner.opt_critic, torch.from_numpy(d["critic"]).to(dev), t_frac,
                       rewards, running, p.normalize_advantage, p.max_grad_norm)
    values, adv, ret, n = crit.values, crit.adv, crit.returns, crit.n
    tt, bb = np.nonzero(running)
    groups_on = group_major(learner.gs, d["controlled"][tt, bb], False).any(-1).numpy() & d["ref_new"][tt, bb].T
    n_group = torch.tensor(float(max(1, groups_on.sum())))  # group-steps where mu drew r
    n_robot = torch.tensor(float(max(1, d["controlled"][tt, bb].sum())))
    ref_coef = p.entropy_coef if p.ref_entropy_coef is None else p.ref_entropy_coef
    adv_r = adv[..., None].expand(-1, -1, learner.gs.n_groups)  # (T, B, Z) weight of log mu(r^z)
    if p.ref_advantage == "group":
        adv_r = group_advantage(learner, values, d["group_reward"], running, p.normalize_advantage)

    learner.opt_policy.zero_grad(set_to_none=True)
    sums = {"actor_loss": 0.0, "critic_loss": crit.loss, "entropy_ref": 0.0, "entropy_local": 0.0}
    rows = p.update_chunk * running.shape[1]
    for s in range(0, len(tt), rows):
        r_t, r_b = tt[s : s + rows], bb[s : s + rows]
        ctl = d["controlled"][r_t, r_b]
        ref = torch.from_numpy(np.ascontiguousarray(d["ref"][r_t, r_b].T)).to(dev)  # (Z, M)
        with autocast(learner.opt_policy):  # precision.py: the policies' forward, float32 losses
            _, ref_logp, logp = policy_forward(learner.reference, learner.local, learner.gs, d["own"][r_t, r_b],
                                               d["nbr"][r_t, r_b], ctl, d["action_mask"][r_t, r_b], ref)
        ref_logp, logp = to_fp32(ref_logp), to_fp32(logp)
        mask = group_major(learner.gs, ctl, fill=False, device=dev)  # (Z, M, n)
        active = mask.any(-1)  # groups with a robot to steer
        decided = active & torch.from_numpy(np.ascontiguousarray(d["ref_new"][r_t, r_b].T)).to(dev)  # mu drew r
        u = group_major(learner.gs, d["proposed"][r_t, r_b], fill=WAIT, device=dev)
        lp_u = (logp.gather(-1, u.unsqueeze(-1)).squeeze(-1) * mask).sum(-1)  # log pi(U~ | w)
        lp_r = ref_logp.gather(-1, ref.unsqueeze(-1)).squeeze(-1) * decided  # log mu(r | o)
        actor = -((adv[r_t, r_b] * lp_u.sum(0)).sum()  # eq:losses (L_l + L_r)
                  + (adv_r[r_t, r_b].T * lp_r).sum()) / n
        ent_r = (_entropy(ref_logp) * decided).sum() / n_group
        ent_u = (_entropy(logp) * mask).sum() / n_robot
        (actor - ref_coef * ent_r - p.entropy_coef * ent_u).backward()
        for key, val in (("actor_loss", actor), ("entropy_ref", ent_r), ("entropy_local", ent_u)):
            sums[key] += float(val.detach())
    probes = kl_probes(learner, d, tt, bb)
    grad_norm = clip_and_step(learner.opt_policy, p.max_grad_norm)
    sums["return_mean"] = float((ret * torch.from_numpy(running.astype(np.float32)).to(dev)).sum() / n)
    ctl_run = d["controlled"][tt, bb]
    return {**sums, **crit.diagnostics(), "diag_entropy": sums["entropy_local"],
            "diag_entropy_ref": sums["entropy_ref"], "diag_grad_norm": grad_norm,
            "diag_kl": probes[1].kl(), "diag_kl_ref": probes[0].kl(),
            "diag_wait_share": wait_share(d["proposed"][tt, bb], ctl_run)}


def kl_probes(learner: Learner, d: dict[str, np.ndarray], tt: np.ndarray, bb: np.ndarray,
              ) -> tuple[KLProbe, KLProbe]:
    """KL probes of the reference (over the group-steps where mu drew r) and of the local
    policy (over the controlled robots) on a strided subset of the running steps, with the
    stored references (diagnostics only; no draw)."""
    k = probe_rows(len(tt), 16)
    r_t, r_b = tt[k], bb[k]
    ctl = d["controlled"][r_t, r_b]
    dev = learner.device
    ref = torch.from_numpy(np.ascontiguousarray(d["ref"][r_t, r_b].T)).to(dev)
    mask = group_major(learner.gs, ctl, fill=False, device=dev)
    decided = mask.any(-1) & torch.from_numpy(np.ascontiguousarray(d["ref_new"][r_t, r_b].T)).to(dev)

    def level(which: int, weight: torch.Tensor) -> KLProbe:
        def log_probs() -> tuple[torch.Tensor, torch.Tensor]:
            out = policy_forward(learner.reference, learner.local, learner.gs, d["own"][r_t, r_b],
                                 d["nbr"][r_t, r_b], ctl, d["action_mask"][r_t, r_b], ref)
            return out[which], weight
        return KLProbe(log_probs)

    return level(1, decided), level(2, mask)


def group_advantage(learner: Learner, values: torch.Tensor, group_reward: np.ndarray,
                    running: np.ndarray, normalize: bool) -> torch.Tensor:
    """(T, B, Z) per-group advantage for the reference (``ref_advantage="group"``, a departure
    from eq:advantage): group z's Monte-Carlo return of its own reward share minus the
    team value scaled by its share of the robots, n_z / N; RMS-normalized over running steps."""
    t, b, z = group_reward.shape
    dev = values.device
    g = mc_returns(group_reward.reshape(t, b * z)).reshape(t, b, z).to(dev)
    share = torch.from_numpy(learner.gs.slot_valid.sum(1) / learner.n_robots).to(dev, torch.float32)
    adv = (g - values[..., None] * share).detach()
    mask = torch.from_numpy(running.astype(np.float32)).to(dev)[..., None]
    if normalize:
        rms = torch.sqrt(((adv * mask) ** 2).sum() / (mask.sum() * z).clamp_min(1.0)).clamp_min(1e-6)
        adv = adv / rms
    return adv * mask


def predictor_targets(gs: GroupStructure, buf: RolloutBuffer, device: torch.device | str = "cpu",
                      ) -> dict[str, torch.Tensor]:
    """Group-major (Z, T, B, ...) training tensors of the predictor from a rollout buffer,
    on ``device``."""
    t_used = buf.t
    msgs = buf.data["msgs"][:t_used]  # (T, B, Z, n, D)
    avail = buf.data["avail"][:t_used]  # (T, B, Z, K)
    age = buf.data["age"][:t_used]
    nb = np.maximum(gs.neighbors, 0)  # (Z, K)
    t_idx = np.arange(t_used)[:, None, None, None] - age
    b_idx = np.arange(msgs.shape[1])[None, :, None, None]
    link = msgs[:, :, nb]  # (T, B, Z, K, n, D)
    mem = msgs[t_idx, b_idx, nb[None, None]]  # last received rows, (T, B, Z, K, n, D)
    lost = ~avail & gs.link_valid[None, None] & buf.running[:t_used, :, None, None]

    def gm(a: np.ndarray) -> torch.Tensor:  # (T, B, Z, ...) -> (Z, T, B, ...)
        return torch.from_numpy(np.ascontiguousarray(np.moveaxis(a, 2, 0))).to(device)

    sender_slots = gs.slot_valid[nb] & gs.link_valid[..., None]  # (Z, K, n)
    return {
        "link": gm(link), "mem": gm(mem), "avail": gm(avail), "age": gm(age), "lost": gm(lost),
        "own": gm(msgs), "slots": torch.from_numpy(sender_slots).to(device),
        "n_group_steps": torch.tensor(float(max(1, buf.running[:t_used].sum() * gs.n_groups))),
    }


def predictor_loss_on(model: GroupPredictor, data: dict[str, torch.Tensor], chunk: int) -> torch.Tensor:
    """L_c (eq:gru_pred_loss) of ``model`` on ``predictor_targets`` data, unrolled from the
    episode start (h = 0); differentiable. The encoder and decoder run over ``chunk`` time
    steps (resp. ``chunk`` x B x K lost links) at a time, the loss summed over the chunks."""
    z, t_used, b, k = data["avail"].shape
    avail_f = data["avail"].unsqueeze(-1).unsqueeze(-1).to(torch.float32)
    def rows(a: torch.Tensor, sl: slice) -> torch.Tensor:  # (Z, T, B, ...) -> (Z, t*B, ...)
        return a[:, sl].reshape(z, -1, *a.shape[3:])

    xs = []
    for s in range(0, t_used, chunk):
        sl = slice(s, s + chunk)
        x = model.encode(rows(data["link"] * avail_f, sl), rows(data["avail"], sl),
                         rows(data["age"], sl), rows(data["own"], sl))
        xs.append(x.reshape(z, -1, b, k, x.shape[-1]))
    x = torch.cat(xs, dim=1)
    dev = data["link"].device
    h = torch.zeros(z, b, k, model.hidden, device=dev)
    hs = []
    # eq:recurrent_predictor over the episode: the input half of the GRU for every step in
    # one matmul, the recurrent half step by step (unbind: one backward for all steps).
    gi_t = model.input_gates(x).unbind(1)
    for t in range(t_used):
        h = model.step_from_gates(gi_t[t], h)
        hs.append(h)
    hid = torch.stack(hs, dim=1)  # (Z, T, B, K, H)
    # Decode only the lost links (the loss ignores the others), padded per group.
    lost = data["lost"].reshape(z, -1)
    idx = [torch.nonzero(lost[g]).squeeze(-1) for g in range(z)]
    width = max(1, max(len(i) for i in idx))
    sel = torch.zeros(z, width, dtype=torch.int64, device=dev)
    valid = torch.zeros(z, width, dtype=torch.bool, device=dev)
    for g, i in enumerate(idx):
        sel[g, : len(i)], valid[g, : len(i)] = i, True
    k_of = sel % k
    slots = data["slots"][torch.arange(z, device=dev)[:, None], k_of]  # (Z, W, n)

    def pick(a: torch.Tensor) -> torch.Tensor:
        flat = a.reshape(z, t_used * b * k, *a.shape[4:])
        return flat[torch.arange(z, device=dev)[:, None], sel]

    h_sel, mem, age, target = pick(hid), pick(data["mem"]), pick(data["age"]), pick(data["link"])
    total = torch.zeros(())
    step = max(1, chunk * b * k)  # lost links decoded at a time
    for s in range(0, width, step):
        sl = slice(s, s + step)

        pred = model.decode(h_sel[:, sl], mem[:, sl], age[:, sl])
        total = total + predictor_loss(pred, target[:, sl], valid[:, sl], slots[:, sl], data["n_group_steps"])
    return total


def predictor_update(learner: Learner, buf: RolloutBuffer) -> dict[str, float]:
    """One Adam step of the GRU predictors on L_c; nothing to learn without lost messages."""
    data = predictor_targets(learner.gs, buf, learner.device)
    if not bool(data["lost"].any()):
        return {"predictor_loss": float("nan")}
    learner.opt_predictor.zero_grad(set_to_none=True)
    loss = predictor_loss_on(learner.predictor, data, learner.params.update_chunk)
    loss.backward()
    torch.nn.utils.clip_grad_norm_(learner.predictor.parameters(), learner.params.max_grad_norm)
    learner.opt_predictor.step()
    return {"predictor_loss": float(loss.detach())}
