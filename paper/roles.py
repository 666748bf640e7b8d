"""The method-role table of the paper: its own method and the baselines it is compared with.

The roles belong to the paper, not to the methods: ``hierarchical`` is the paper's method
(``REFERENCE``), ``decentralized`` and ``ic3net`` its baselines (Sec. IV), ``pibt`` the
planner reference this reproduction adds (``BASELINE``). A plugin that still declares
``Method.paper_role`` keeps that role (read here, for the claims of a run's own methods).
"""
from __future__ import annotations

from algorithms.base import BASELINE, REFERENCE
from algorithms.registry import find_method

__all__ = ["FIG1_METHODS", "FIG2_METHODS", "FIG3_METHODS", "REFERENCE_METHOD", "ROLES", "has_role", "role"]

REFERENCE_METHOD = "hierarchical"
ROLES = {REFERENCE_METHOD: REFERENCE, "decentralized": BASELINE, "ic3net": BASELINE, "pibt": BASELINE}
FIG1_METHODS = (REFERENCE_METHOD, "decentralized")  # Fig. 1: training convergence
FIG2_METHODS = (REFERENCE_METHOD, "ic3net")  # Fig. 2: success-rate percentiles
FIG3_METHODS = (REFERENCE_METHOD, "decentralized")  # Fig. 3: payload against all-to-all


def role(method: str) -> str:
    """REFERENCE, BASELINE or "" (a method of the user's own)."""
    if method in ROLES:
        return ROLES[method]
    cls = find_method(method)
    return str(getattr(cls, "paper_role", "")) if cls is not None else ""


def has_role(method: str) -> bool:
    """Whether ``method`` is one of the paper's (its own method or a baseline)."""
    return role(method) != ""
