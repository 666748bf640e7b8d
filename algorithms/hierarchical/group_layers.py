"""Layers with one set of weights per group, applied to all groups in one batched matmul.

The paper gives every group its own parameters (psi_z, theta_z, eta_z; Sec. II, Alg. 2).
Instead of Z separate modules run in a Python loop, each layer here stores its weights
stacked along a leading group axis, shaped (G, in, out), and consumes tensors whose first
axis is the group axis, shaped (Z, ..., in). With ``G == 1`` (parameter sharing) the single
weight set serves every group. Padding of sets (groups of different sizes) is handled by
the callers with masks; ``masked_mean`` pools over a set axis.

Seed stacking (``algorithms/common/seed_stack.py``): the rollout of S cells that differ only
in their seed runs as one batch. Their per-group weights are stacked group-major,
(Z x S, in, out) with row z S + s holding seed s's group z, and ``seeds = S`` is set on
every layer; inputs stay (Z, S x B, ...) with the episodes of seed s in rows s B..(s+1) B,
so ``x.reshape(Z S, -1, in)`` is a view whose slice z S + s is seed s's group z, and one
batched matmul computes every slice exactly as the seed's own matmul would (same shapes per
slice; tests/algorithms/hierarchical/test_seed_stack.py). With shared parameters the S seeds'
weights are (S, in, out), repeated Z times (``per_slice``).
"""
from __future__ import annotations

import math

import torch
from torch import nn


class GroupLinear(nn.Module):
    """y[z] = x[z] @ W[z] + b[z]; x (Z, ..., in) -> (Z, ..., out)."""

    seeds = 1  # S > 1: weights stacked for S seeds (module docstring)

    def __init__(self, n_param_groups: int, n_groups: int, d_in: int, d_out: int) -> None:
        super().__init__()
        if n_param_groups not in (1, n_groups):
            raise ValueError(f"n_param_groups must be 1 or {n_groups}, got {n_param_groups}")
        self.n_groups = n_groups
        bound = 1.0 / math.sqrt(d_in)  # the default init of nn.Linear, per group
        self.weight = nn.Parameter(torch.empty(n_param_groups, d_in, d_out).uniform_(-bound, bound))
        self.bias = nn.Parameter(torch.empty(n_param_groups, 1, d_out).uniform_(-bound, bound))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        z = x.shape[0] * self.seeds
        flat = x.reshape(z, -1, x.shape[-1])
        out = torch.baddbmm(per_slice(self.bias, z), flat, per_slice(self.weight, z))
        return out.reshape(*x.shape[:-1], out.shape[-1])


class GroupMLP(nn.Module):
    """Per-group MLP with ReLU between layers (none after the last); (Z, ..., in) -> (Z, ..., out)."""

    def __init__(self, n_param_groups: int, n_groups: int, sizes: list[int],
                 final_activation: bool = False) -> None:
        super().__init__()
        self.layers = nn.ModuleList(
            GroupLinear(n_param_groups, n_groups, a, b) for a, b in zip(sizes[:-1], sizes[1:], strict=True)
        )
        self.final_activation = final_activation

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        for k, layer in enumerate(self.layers):
            x = layer(x)
            if k < len(self.layers) - 1 or self.final_activation:
                x = relu(x)
        return x


class GroupGRUCell(nn.Module):
    """A GRU cell per group (same gate equations as ``torch.nn.GRUCell``).

    x (Z, ..., in), h (Z, ..., H) -> h' (Z, ..., H).
    """

    def __init__(self, n_param_groups: int, n_groups: int, d_in: int, hidden: int) -> None:
        super().__init__()
        self.hidden = hidden
        self.ih = GroupLinear(n_param_groups, n_groups, d_in, 3 * hidden)
        self.hh = GroupLinear(n_param_groups, n_groups, hidden, 3 * hidden)

    def forward(self, x: torch.Tensor, h: torch.Tensor) -> torch.Tensor:
        return self.from_input_gates(self.ih(x), h)

    def from_input_gates(self, gi: torch.Tensor, h: torch.Tensor) -> torch.Tensor:
        """The step with the input's gate pre-activations ``gi = ih(x)`` (Z, ..., 3H) already
        computed, e.g. for a whole sequence in one matmul before a time loop."""
        gh = self.hh(h)
        i_r, i_z, i_n = gi.chunk(3, dim=-1)
        h_r, h_z, h_n = gh.chunk(3, dim=-1)
        r = torch.sigmoid(i_r + h_r)
        u = torch.sigmoid(i_z + h_z)
        n = torch.tanh(i_n + r * h_n)
        return (1.0 - u) * n + u * h


def per_slice(param: torch.Tensor, z: int) -> torch.Tensor:
    """A parameter stacked on its leading axis as the z = Z S slices of the inputs: per
    group (leading axis z) as it is; shared by the groups (1) expanded; shared and S
    seeds stacked (S) repeated Z times, so slice z S + s holds seed s's parameters."""
    g = param.shape[0]
    if g == z:
        return param
    if g == 1:
        return param.expand(z, *param.shape[1:])
    return param.repeat(z // g, *(1,) * (param.dim() - 1))


def relu(x: torch.Tensor) -> torch.Tensor:
    """ReLU in place when no graph is recorded (rollouts), else out of place: an in-place
    ReLU on a layer's output (a reshaped view of the matmul result) makes autograd clone
    and scatter the whole tensor in backward (CopySlices). Same values either way."""
    return torch.relu(x) if torch.is_grad_enabled() else torch.relu_(x)


def masked_mean(x: torch.Tensor, mask: torch.Tensor, dim: int) -> torch.Tensor:
    """Mean of ``x`` over set axis ``dim`` where ``mask`` (x.shape without the feature axis)
    is True; an empty set gives zeros.

    Over the set axis next to the features (dim -2, every caller) the masked sum is one
    batched matrix product (mask row vector @ x) instead of a masked copy of ``x`` and a
    reduction; equal up to float summation order (tests/algorithms/hierarchical). Its
    backward is the outer product mask x grad, the same numbers as autograd's bmm backward
    with an inner size of 1, without its one-column matrix products."""
    m = mask.to(x.dtype)
    if dim in (-2, x.dim() - 2):
        # Without a graph (rollouts) the product itself: Function.apply's bookkeeping costs
        # more than the bmm at rollout sizes; the same kernel, the same numbers.
        total = _MaskedSum.apply(x, m) if torch.is_grad_enabled() else _masked_sum(x, m)
        return total / m.sum(dim=-1, keepdim=True).clamp_min(1.0)
    m = m.unsqueeze(-1)
    return (x * m).sum(dim=dim) / m.sum(dim=dim).clamp_min(1.0)


class _MaskedSum(torch.autograd.Function):
    """sum_i m_i x_i over the set axis -2 as one batched (1 x n) @ (n x d) product per row.

    Autograd's backward of that bmm is a bmm with inner size 1 (slow on CPU for many tiny
    rows); the gradient here, m_i * g, is each of its entries computed the same way (one
    product, nothing summed), so it is bit-identical and an order of magnitude faster.
    The mask gets no gradient."""

    @staticmethod
    def forward(ctx, x: torch.Tensor, m: torch.Tensor) -> torch.Tensor:
        ctx.save_for_backward(m)
        return _masked_sum(x, m)

    @staticmethod
    def backward(ctx, grad: torch.Tensor) -> tuple[torch.Tensor, None]:
        (m,) = ctx.saved_tensors
        return m.unsqueeze(-1) * grad.unsqueeze(-2), None


def _masked_sum(x: torch.Tensor, m: torch.Tensor) -> torch.Tensor:
    """sum_i m_i x_i over axis -2: x (..., n, d), m (..., n) -> (..., d), one bmm."""
    n, d = x.shape[-2], x.shape[-1]
    return torch.bmm(m.reshape(-1, 1, n), x.reshape(-1, n, d)).reshape(*x.shape[:-2], d)
