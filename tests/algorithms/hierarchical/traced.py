"""TracedHierarchical: the hierarchical method with each step's intermediates recorded, and
r optionally imposed, for the tests of its structure (Proposition 1, the filter's blocked
map, the variants). A test-only subclass: the method itself carries no tracing; it
overrides the method's own steps (``_receive``, ``policy_forward``, ``_reference_input``)
and wraps its safety filter, and changes no number.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import torch

from algorithms.common.execution import ActionChoice
from algorithms.hierarchical.method import Controller, HierarchicalMethod, Received
from algorithms.hierarchical.safety_filter import SafetyFilter


class _RecordingFilter:
    """Wraps a SafetyFilter: keeps the step's blocked map and its first call's fallbacks."""

    def __init__(self, inner: SafetyFilter, trace: dict[str, Any], groups: int) -> None:
        self.inner, self.trace, self.groups, self.first = inner, trace, groups, False

    def blocked_cells(self, *args: Any) -> np.ndarray:
        out = self.inner.blocked_cells(*args)
        self.trace["blocked"] = out.reshape(-1, self.groups, out.shape[-1])  # (B, Z, cells)
        self.first = True
        return out

    def __call__(self, *args: Any) -> Any:
        res = self.inner(*args)
        if self.first:  # a view: a resample on fallback updates it in place
            self.trace["filter_fallback"] = res.fallback.reshape(-1, self.groups)  # (B, Z)
            self.first = False
        return res


class TracedHierarchical(HierarchicalMethod):
    """``trace`` holds the last decided step's intermediates; ``fixed_ref`` (Z, B), when
    set, is imposed as r at every step (not counted as mu's decision)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.trace: dict[str, Any] = {}
        self.fixed_ref: np.ndarray | None = None
        self.filter = _RecordingFilter(self.filter, self.trace, self.env.groups)  # type: ignore[assignment]

    def _receive(self, core: Any, state: Controller, avail: np.ndarray) -> Received:
        rx = super()._receive(core, state, avail)
        self.trace.update(m_hat=rx.m_hat, cells=rx.cells, present=rx.present, link_msgs=rx.link_msgs,
                          avail=rx.avail, lost=rx.lost)
        return rx

    def _reference_input(self, state: Controller, batch: int, gen: torch.Generator,
                         ) -> tuple[torch.Tensor | None, np.ndarray]:
        if self.fixed_ref is not None:
            return torch.as_tensor(np.asarray(self.fixed_ref, dtype=np.int64)), np.zeros((self.env.groups, 1), bool)
        return super()._reference_input(state, batch, gen)

    def policy_forward(self, own: np.ndarray, nbr: np.ndarray, controlled: np.ndarray,
                       action_mask: np.ndarray, ref: torch.Tensor | None,
                       choice: ActionChoice | None = None,
                       ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        out = super().policy_forward(own, nbr, controlled, action_mask, ref, choice)
        if choice is not None:  # the rollout's call (the updates pass r and no choice)
            self.trace.update(own=own, nbr=nbr, controlled=controlled, action_mask=action_mask,
                              ref=out[0], ref_logp=out[1], logp=out[2])
        return out
