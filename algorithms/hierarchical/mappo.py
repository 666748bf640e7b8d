"""The hierarchical method's update under ``protocol="mappo"`` (algorithms/common/ppo.py;
docs/decisions/0201).

The protocol's per-robot critic gives GAE advantages per robot; the two levels learn from
the credit their structure allows:

* the local policy pi's per-robot factors: each robot's own advantage (``credit="robot"``)
  or the team's (``"team"``);
* the reference mu of group z: the GAE advantage of its group, whose reward is the sum of
  its robots' terms and whose value the sum of their values.

The samples are the running (t, b) steps; each carries Z reference ratios (where mu drew r)
and Z n local ratios (controlled robots), on the stored references and proposed controls
(the policy gradient is on the sampled outputs, the filter part of the transition, as in
the paper update). The GRU predictors keep their own supervised update.
May import: algorithms.common, algorithms.hierarchical (messages, policies, training).
"""
from __future__ import annotations

import numpy as np
import torch

from algorithms.common.diagnostics import wait_share
from algorithms.common.ppo import PPOBatch, RobotCritic, gae, mappo_critic, ppo_actor_update, update_generator
from algorithms.common.trainer import RolloutBuffer
from algorithms.hierarchical.messages import GroupStructure
from algorithms.hierarchical.policies import group_major, policy_forward
from algorithms.hierarchical.training import Learner
from envs.actions import WAIT

__all__ = ["mappo_policy_update", "ratio_advantages"]


def ratio_advantages(gs: GroupStructure, group_adv: torch.Tensor, robot_adv: torch.Tensor, local_credit: str,
                     ) -> torch.Tensor:
    """The advantage of every ratio of M samples, (M, Z + Z n): mu of group z takes its
    group's advantage ``group_adv`` (M, Z); pi's factor of slot j of group z takes the same
    group advantage (``local_credit = "group"``: the joint-Wait fallback stops a group's
    robots together, so a robot's own terms miss what its proposal costs the others) or its
    robot's entry of ``robot_adv`` (M, N) (``"credit"``: the shared ``credit``)."""
    m = group_adv.shape[0]
    if local_credit == "group":
        local = group_adv[:, :, None].expand(-1, -1, gs.n_slots)  # (M, Z, n)
    else:
        local = group_major(gs, robot_adv.cpu().numpy(), fill=0.0, device=group_adv.device).permute(1, 0, 2)
    return torch.cat([group_adv, local.reshape(m, -1)], dim=1)


def mappo_policy_update(learner: Learner, buf: RolloutBuffer, seed: int, iteration: int) -> dict[str, float]:
    """One ``mappo`` update of mu, pi and the protocol's critic from a finished batch."""
    p, gs = learner.params, learner.gs
    assert isinstance(learner.critic, RobotCritic)
    t_used = buf.t
    d = {k: v[:t_used] for k, v in buf.data.items()}
    running = buf.running[:t_used]
    dev = learner.device
    t_frac = torch.from_numpy(
        np.broadcast_to((np.arange(t_used, dtype=np.float32) / learner.horizon)[:, None], running.shape).copy()).to(dev)
    gen = update_generator(seed, iteration)
    crit = mappo_critic(learner.critic, learner.opt_critic, buf, p, t_frac, gen)

    def sum_group(x: torch.Tensor) -> torch.Tensor:  # (T, B, N) -> (T, B, Z): summed over each group's robots
        per_slot = gs.gather(x.reshape(-1, x.shape[-1]).cpu().numpy(), fill=0.0)
        return torch.from_numpy(per_slot.sum(-1).reshape(*x.shape[:2], -1)).to(dev)

    group_adv, _ = gae(sum_group(crit.rewards), sum_group(crit.values), crit.running, p.gamma, p.gae_lambda)
    tt, bb = np.nonzero(running)
    z = gs.n_groups
    advantages = ratio_advantages(gs, group_adv[tt, bb], crit.robot_adv[tt, bb], p.local_credit)

    def log_probs(ix: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        r_t, r_b = tt[ix.numpy()], bb[ix.numpy()]
        ctl = d["controlled"][r_t, r_b]
        ref = torch.from_numpy(np.ascontiguousarray(d["ref"][r_t, r_b].T)).to(dev)  # (Z, K)
        _, ref_logp, logp = policy_forward(learner.reference, learner.local, gs, d["own"][r_t, r_b],
                                           d["nbr"][r_t, r_b], ctl, d["action_mask"][r_t, r_b], ref)
        mask = group_major(gs, ctl, fill=False, device=dev)  # (Z, K, n)
        decided = mask.any(-1) & torch.from_numpy(np.ascontiguousarray(d["ref_new"][r_t, r_b].T)).to(dev)
        u = group_major(gs, d["proposed"][r_t, r_b], fill=WAIT, device=dev)
        lp_u = logp.gather(-1, u.unsqueeze(-1)).squeeze(-1)  # (Z, K, n)
        lp_r = ref_logp.gather(-1, ref.unsqueeze(-1)).squeeze(-1)  # (Z, K)
        ent_u = -(logp.exp() * logp).sum(-1)
        ent_r = -(ref_logp.exp() * ref_logp).sum(-1)
        k = len(ix)

        def flat(ref_part: torch.Tensor, local_part: torch.Tensor) -> torch.Tensor:  # -> (K, Z + Z n)
            return torch.cat([ref_part.T, local_part.permute(1, 0, 2).reshape(k, -1)], dim=1)

        return flat(lp_r, lp_u), flat(ent_r, ent_u), flat(decided.float(), mask.float())

    levels = torch.cat([torch.zeros(z, dtype=torch.long), torch.ones(z * gs.n_slots, dtype=torch.long)])
    batch = PPOBatch(len(tt), log_probs, advantages, levels, ("ref", ""))  # each level normalized on its own
    out = ppo_actor_update(batch, learner.opt_policy, p.ppo_epochs, p.ppo_minibatches, p.ppo_clip, p.entropy_coef,
                           p.max_grad_norm, gen)
    assert advantages.shape[1] == z + z * gs.n_slots
    return {**crit.losses, **out, "entropy_local": out["diag_entropy"], "entropy_ref": out["diag_entropy_ref"],
            "diag_wait_share": wait_share(d["proposed"][tt, bb], d["controlled"][tt, bb])}
