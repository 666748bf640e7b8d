"""A linear, action-aligned logit path: logit(a) += ACTION_GAIN * v . phi(o, a).

phi(o, a) are observation columns that describe action a (its shortest-path progress,
robots known to be on the cell it leads to, ...), picked by an index table (K, 5); v (K,)
starts at zero, so the path adds nothing at initialization, and ACTION_GAIN makes Adam /
RMSprop move it an order of magnitude faster than the MLP weights. With one team reward
over many robots the policy gradient is weak; this path lets a policy learn the obvious
"make progress, avoid occupied cells" rule early. The hierarchical local policy has the
same path (per group); the baselines use this module so all learned methods get it alike
(docs/decisions/0136, 0137).
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

ACTION_GAIN = 10.0


class ActionPath(nn.Module):
    """Adds ACTION_GAIN * sum_k v_k obs[..., index[k, a]] to logit a."""

    index: torch.Tensor  # buffer (K, 5): the obs column of each term of each action

    def __init__(self, index: np.ndarray) -> None:
        super().__init__()
        self.register_buffer("index", torch.as_tensor(np.asarray(index), dtype=torch.int64))  # (K, 5)
        self.weight = nn.Parameter(torch.zeros(self.index.shape[0]))

    def forward(self, obs: torch.Tensor, logits: torch.Tensor) -> torch.Tensor:
        """obs (..., F), logits (..., 5) -> logits (..., 5)."""
        # index_select of the flattened table: the same (..., K, 5) values and layout as
        # obs[..., index], without advanced indexing's overhead.
        k, a = self.index.shape
        phi = obs.index_select(-1, self.index.reshape(-1)).view(*obs.shape[:-1], k, a).transpose(-1, -2)
        return logits + ACTION_GAIN * (phi * self.weight).sum(-1)  # phi: (..., 5, K)


def progress_index() -> np.ndarray:
    """(1, 5) columns of ``own_features`` holding each action's shortest-path progress."""
    return np.arange(6, 11)[None, :]
