"""Running normalization of value targets (MAPPO's ValueNorm, Yu et al. 2022).

A value head trained on raw 500-step team returns (hundreds) through a trunk it shares
with the policy lets the value gradient reshape the trunk in the first updates and
collapse the policy. With ``ValueNorm`` the head predicts normalized returns
(G - mu) / sigma; mu and sigma are debiased exponential moving averages of the returns
of each training batch, kept as buffers so checkpoints carry them.
"""
from __future__ import annotations

import torch
from torch import nn


class ValueNorm(nn.Module):
    """Debiased EMA of the mean and second moment of value targets (scalars)."""

    mean: torch.Tensor  # buffers (float64 scalars): EMA of G, of G^2, and the debiasing weight
    mean_sq: torch.Tensor
    weight: torch.Tensor

    def __init__(self, beta: float = 0.99, min_var: float = 1e-2) -> None:
        super().__init__()
        self.beta, self.min_var = beta, min_var
        self.register_buffer("mean", torch.zeros((), dtype=torch.float64))
        self.register_buffer("mean_sq", torch.zeros((), dtype=torch.float64))
        self.register_buffer("weight", torch.zeros((), dtype=torch.float64))

    def stats(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(mu, sigma) as float32 scalars; (0, 1) before the first update."""
        if float(self.weight) == 0.0:
            return torch.zeros(()), torch.ones(())
        mu = self.mean / self.weight
        var = (self.mean_sq / self.weight - mu**2).clamp_min(self.min_var)
        return mu.float(), var.sqrt().float()

    @torch.no_grad()
    def update(self, targets: torch.Tensor, mask: torch.Tensor) -> None:
        """Fold in the masked entries of one batch of targets (any shape, mask alike)."""
        m = mask.to(torch.float64)
        n = m.sum()
        if float(n) == 0.0:
            return
        x = targets.to(torch.float64)
        b = self.beta
        self.mean.mul_(b).add_((1 - b) * (x * m).sum() / n)
        self.mean_sq.mul_(b).add_((1 - b) * (x**2 * m).sum() / n)
        self.weight.mul_(b).add_(1 - b)

    def normalize(self, x: torch.Tensor) -> torch.Tensor:
        mu, sigma = self.stats()
        return (x - mu) / sigma

    def denormalize(self, y: torch.Tensor) -> torch.Tensor:
        mu, sigma = self.stats()
        return y * sigma + mu
