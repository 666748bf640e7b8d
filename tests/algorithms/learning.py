"""Shared helper of the methods' learning tests."""
from __future__ import annotations

import numpy as np

from algorithms.base import Method


def eval_success(method: Method, chunks: int = 2) -> float:
    """Mean success rate over the first ``chunks`` evaluation chunks (fixed scenarios)."""
    return float(np.mean([r["success_rate"] for c in range(chunks) for r in method.evaluate(c)]))
