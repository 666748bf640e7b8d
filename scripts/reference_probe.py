"""Does the reference r carry information? Measurements on a trained hierarchical method.

The paper's reference policy mu_psi_z (eq:reference_policy) is meant to pass inter-group
information to the local policy (Proposition 1: S-hat reaches pi only through r). A
reference that learned nothing is uniform, ignores the state, and acts on pi as noise.
``probe_reference`` runs evaluation episodes and measures, per active group-step:

* ``ref_entropy``: mean entropy H(mu(. | o)) in nats (uniform: log |R_z|);
* ``mi_ref_state``: I(r; o) = H(E_o mu(. | o)) - E_o H(mu(. | o)), nats: how much the
  choice of r depends on the group's observation (0 when mu ignores it);
* ``mi_ref_control``: I(r; u_i | s) per controlled robot under r ~ mu, nats: how much r
  moves the robot's control distribution, sum_r mu(r) KL(pi(. | s, r) || sum_r' mu(r') pi(. | s, r'));
* ``modal_ref_share``: fraction of group-steps on which the argmax r is the group's most
  frequent argmax r over the probe (1.0: a constant reference);
* ``argmax_success`` vs ``uniform_success``: evaluation success with r = argmax mu, and
  with r drawn uniformly (everything else identical, argmax local controls).

Pure measurement: evaluation streams only, the method's parameters are not touched. The
probe runs ``ProbedHierarchical``, a subclass of the method (a copy of its weights) that
records mu's inputs and log-probs in ``policy_forward`` and can draw r uniformly: the
method itself carries no probe code. Imported by maintenance/probe_reference.py and
maintenance/reference_study.py (run from the repository root: ``python maintenance/...``).
"""
from __future__ import annotations

from typing import Any

import numpy as np
import torch

from algorithms.common.episodes import EVAL_STREAM, EpisodeBatch, EpisodeStats, batch_rng
from algorithms.common.execution import ARGMAX_CHOICE, ActionChoice
from algorithms.hierarchical.method import Controller, HierarchicalMethod
from algorithms.hierarchical.policies import group_major


def _entropy(logp: torch.Tensor) -> torch.Tensor:
    return -(logp.exp() * logp).sum(-1)


class ProbedHierarchical(HierarchicalMethod):
    """The method with each rollout step's mu inputs and log-probs kept (``step``), and r
    drawn uniformly from R_z instead of from mu when ``uniform`` (never counted as mu's)."""

    uniform = False
    step: dict[str, Any]

    @classmethod
    def of(cls, method: HierarchicalMethod) -> ProbedHierarchical:
        """A probe with ``method``'s configuration and current weights (global RNG kept);
        uniform draws of r come from ``method``'s own training generator, as they always did."""
        rng = torch.get_rng_state()
        probe = cls(method.env, method.params.model_dump(), seed=method.seed)
        torch.set_rng_state(rng)
        probe.torch_gen = method.torch_gen
        for key, mod in method.modules().items():
            if isinstance(mod, torch.nn.Module):
                probe.modules()[key].load_state_dict(mod.state_dict())
        probe.step = {}
        return probe

    def _reference_input(self, state: Controller, batch: int, gen: torch.Generator,
                         ) -> tuple[torch.Tensor | None, np.ndarray]:
        if self.uniform:
            k = self.params.ref_size
            return torch.randint(k, (self.env.groups, batch), generator=gen), np.zeros((self.env.groups, 1), bool)
        return super()._reference_input(state, batch, gen)

    def policy_forward(self, own: np.ndarray, nbr: np.ndarray, controlled: np.ndarray,
                       action_mask: np.ndarray, ref: torch.Tensor | None,
                       choice: ActionChoice | None = None,
                       ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        out = super().policy_forward(own, nbr, controlled, action_mask, ref, choice)
        self.step = {"own": own, "controlled": controlled, "action_mask": action_mask, "ref_logp": out[1]}
        return out


def _run(method: ProbedHierarchical, batch: EpisodeBatch, uniform: bool,
         acc: dict[str, list[Any]] | None) -> list[dict[str, float]]:
    core = batch.core
    stats = EpisodeStats(core.batch, core.n, method.env.d_m)
    method.uniform = uniform
    state = method.begin(batch, ARGMAX_CHOICE)
    while batch.running:
        running = ~core.ended
        dec = method.decide(batch, state, ARGMAX_CHOICE)
        if acc is not None:
            _accumulate(method, method.step, acc)
        res = core.step(dec.actions)
        stats.add(running, res, dec)
    return stats.finish(core.done)


def _accumulate(method: HierarchicalMethod, tr: dict[str, Any], acc: dict[str, list[Any]]) -> None:
    ref_logp = tr["ref_logp"]  # (Z, B, R)
    mask = group_major(method.gs, tr["controlled"], fill=False)  # (Z, B, n)
    active = mask.any(-1)
    if not bool(active.any()):
        return
    feats = group_major(method.gs, tr["own"]).to(torch.float32)
    amask = group_major(method.gs, tr["action_mask"], fill=True)
    z, b, r_size = ref_logp.shape
    with torch.no_grad():
        per_r = torch.stack([method.local(feats, mask, torch.full((z, b), r, dtype=torch.int64), amask)
                             for r in range(r_size)], dim=2)  # (Z, B, R, n, 5) log pi(u | s, r)
    mu = ref_logp.exp()
    mix = torch.log((mu[..., None, None] * per_r.exp()).sum(2).clamp_min(1e-30))  # (Z, B, n, 5)
    kl = (per_r.exp() * (per_r - mix[:, :, None])).sum(-1)  # (Z, B, R, n)
    mi_u = (mu[..., None] * kl).sum(2)  # (Z, B, n)
    acc["mu"].append(mu[active].numpy())
    acc["mi_u"].append(mi_u[mask].numpy())
    acc["argmax"].append(np.stack([ref_logp.argmax(-1)[active].numpy(),
                                   torch.nonzero(active)[:, 0].numpy()], axis=1))


def probe_reference(method: HierarchicalMethod, batches: int = 2, batch_size: int = 5,
                    seed: int = 0) -> dict[str, float]:
    """Measures of the table above over ``batches`` x ``batch_size`` evaluation episodes
    (the same scenarios and loss draws for the argmax-r and uniform-r runs)."""
    probe = ProbedHierarchical.of(method)
    acc: dict[str, list[Any]] = {"mu": [], "mi_u": [], "argmax": []}
    succ_arg, succ_uni = [], []
    with torch.no_grad():
        for k in range(batches):
            rows = _run(probe, EpisodeBatch(method.env, batch_size, batch_rng(seed, EVAL_STREAM, k),
                                            method.layout), False, acc)
            succ_arg += [r["success_rate"] for r in rows]
            rows = _run(probe, EpisodeBatch(method.env, batch_size, batch_rng(seed, EVAL_STREAM, k),
                                            method.layout), True, None)
            succ_uni += [r["success_rate"] for r in rows]
    mu = np.concatenate(acc["mu"]).astype(np.float64)  # (S, R) every active group-step
    ent = -(mu * np.log(np.maximum(mu, 1e-30))).sum(-1)
    arg = np.concatenate(acc["argmax"])  # (S, 2): argmax r, group
    modal, mi_state = 0, 0.0
    for g in np.unique(arg[:, 1]):  # per group: groups have their own mu
        rows = arg[:, 1] == g
        modal += np.bincount(arg[rows, 0]).max()
        mean_mu = mu[rows].mean(0)
        mi_state += rows.sum() * (-(mean_mu * np.log(np.maximum(mean_mu, 1e-30))).sum() - ent[rows].mean())
    return {
        "ref_entropy": float(ent.mean()),
        "mi_ref_state": float(mi_state / len(arg)),
        "mi_ref_control": float(np.concatenate(acc["mi_u"]).mean()),
        "modal_ref_share": float(modal / len(arg)),
        "argmax_success": float(np.mean(succ_arg)),
        "uniform_success": float(np.mean(succ_uni)),
    }
