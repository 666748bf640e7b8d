"""The names of the per-update training diagnostics (``diag_*``) the train rows carry.

Kept apart from ``diagnostics.py`` (which computes them with torch) so the results store's
schema can name them without importing torch. May import: nothing.
"""
from __future__ import annotations

__all__ = ["DIAGNOSTIC_COLUMNS"]

DIAGNOSTIC_COLUMNS = (
    "diag_entropy", "diag_entropy_ref", "diag_kl", "diag_kl_ref", "diag_grad_norm",
    "diag_critic_grad_norm", "diag_adv_mean", "diag_adv_std", "diag_return_mean", "diag_return_std",
    "diag_explained_variance", "diag_wait_share",
)
