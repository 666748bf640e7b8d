"""Training diagnostics per update: what a learning curve alone cannot tell.

Every learned method's ``update`` adds these ``diag_*`` numbers to the losses it returns;
``Method.finish_iteration`` copies them onto the update's episode rows, the store keeps
them in the train rows (``DIAGNOSTIC_COLUMNS``, NaN in stores written before them and for
a quantity a method does not have) and the trackers see them with every other row value.

* policy entropy per level (``diag_entropy``: the robot-level control policy;
  ``diag_entropy_ref``: the hierarchical reference policy mu);
* approximate KL(pi_old || pi_new) between the policies before and after the update, exact
  for the categorical distributions on a fixed strided subset of the batch's rows
  (``KLProbe``; ``diag_kl``, ``diag_kl_ref``);
* gradient norms before clipping (``diag_grad_norm`` of the policy, ``diag_critic_grad_norm``);
* raw advantage A = G - V and return G statistics over running steps, before any
  normalization, and the critic's explained variance 1 - Var(G - V) / Var(G)
  (``value_diagnostics``);
* the share of Wait among the sampled controls of active robots (``diag_wait_share``).
  Collisions are in every row already (``collision_rate``).

Computing them changes nothing the paper protocol trains: no random draw, no parameter or
optimizer state is touched, the probes run under ``no_grad`` (scripts/train_hashes.py
hashes the training rows without these columns).
May import: envs, algorithms.common.diagnostic_columns.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch

from algorithms.common.diagnostic_columns import DIAGNOSTIC_COLUMNS
from envs.actions import WAIT

__all__ = ["DIAGNOSTIC_COLUMNS", "KLProbe", "entropy_mean", "probe_rows", "value_diagnostics", "wait_share"]

PROBE_ROWS = 2048  # rows of a batch on which the KL is measured (a strided subset)


def probe_rows(total: int, k: int = PROBE_ROWS) -> np.ndarray:
    """Up to ``k`` row indices spread evenly over ``total`` rows (all of them when fewer)."""
    if total <= k:
        return np.arange(total)
    return np.unique(np.linspace(0, total - 1, k).round().astype(np.int64))


def _masked_moments(x: torch.Tensor, mask: torch.Tensor) -> tuple[float, float]:
    m = mask.to(torch.float64)
    n = float(m.sum())
    if n == 0.0:
        return float("nan"), float("nan")
    xd = x.to(torch.float64)
    mean = float((xd * m).sum()) / n
    var = float((((xd - mean) ** 2) * m).sum()) / n
    return mean, var


def value_diagnostics(values: torch.Tensor, returns: torch.Tensor, mask: torch.Tensor) -> dict[str, float]:
    """Raw advantage A = G - V and return G moments over the masked entries, and the
    critic's explained variance 1 - Var(G - V) / Var(G) (NaN when Var(G) = 0)."""
    adv_mean, adv_var = _masked_moments(returns - values, mask)
    ret_mean, ret_var = _masked_moments(returns, mask)
    ev = 1.0 - adv_var / ret_var if ret_var > 0 else float("nan")
    return {"diag_adv_mean": adv_mean, "diag_adv_std": float(np.sqrt(adv_var)),
            "diag_return_mean": ret_mean, "diag_return_std": float(np.sqrt(ret_var)),
            "diag_explained_variance": ev}


def entropy_mean(logp: torch.Tensor, weight: torch.Tensor | None = None) -> float:
    """Mean entropy of categorical log-probabilities (..., A) over the rows (weighted by
    a 0/1 ``weight`` of the leading shape when given)."""
    with torch.no_grad():
        ent = -(logp.exp() * logp).sum(-1)
        if weight is None:
            return float(ent.mean()) if ent.numel() else float("nan")
        w = weight.to(ent.dtype)
        return float((ent * w).sum() / w.sum()) if float(w.sum()) > 0 else float("nan")


def wait_share(actions: np.ndarray, active: np.ndarray) -> float:
    """Share of Wait among ``actions`` where ``active`` (same shape) is set."""
    n = int(active.sum())
    return float(((actions == WAIT) & active).sum() / n) if n else float("nan")


class KLProbe:
    """KL(pi_old || pi_new) across one update on a fixed set of rows.

    ``log_probs`` recomputes, under ``no_grad``, the (rows..., A) log-probabilities of the
    current parameters (and optionally a 0/1 weight of the leading shape, e.g. the active
    robots); it is called once when the probe is made (before the optimizer step) and once
    by ``kl`` (after it). Masked actions have probability 0 under both and add nothing.
    """

    def __init__(self, log_probs: Callable[[], tuple[torch.Tensor, torch.Tensor | None]]) -> None:
        self.log_probs = log_probs
        with torch.no_grad():
            self.old, self.weight = log_probs()

    def kl(self) -> float:
        with torch.no_grad():
            new, _ = self.log_probs()
            per_row = (self.old.exp() * (self.old - new)).sum(-1)
            if self.weight is None:
                return float(per_row.mean()) if per_row.numel() else float("nan")
            w = self.weight.to(per_row.dtype)
            return float((per_row * w).sum() / w.sum()) if float(w.sum()) > 0 else float("nan")
