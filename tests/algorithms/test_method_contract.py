"""The Method contract suite (algorithms/testing.py) run against every registered method.

The same class an outside package subclasses (examples/external_method/tests): traits,
valid actions, metric rows in range, the same scenarios in every mode, an update that
changes the parameters with finite losses (learned methods), the same seed giving the same
numbers, and a checkpoint loaded with ``torch.load(weights_only=True)`` continuing exactly.
"""
from __future__ import annotations

import pytest

from algorithms.registry import available
from algorithms.testing import MethodContract


class TestRegisteredMethods(MethodContract):
    @pytest.fixture(params=sorted(available()))
    def method_spec(self, request: pytest.FixtureRequest) -> str:
        return str(request.param)
