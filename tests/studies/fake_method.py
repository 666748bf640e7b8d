"""A tiny test-only Method with the hierarchical method's tuned parameters.

Its controller is greedy shortest-path progress with a random action with probability
``1 / ref_size`` (evaluation included), so a larger ``ref_size`` gives a higher success
rate: studies can be tested for pruning and ranking without the real method. ``update``
learns nothing. With ``crash_file`` set, the first ``train_iteration`` anywhere creates that
file and kills its own process (a crashed worker); later ones run normally. The file is
created atomically, so two workers that start at once cannot both crash.
"""
from __future__ import annotations

import os
from typing import Any

import numpy as np
from pydantic import Field

from algorithms.base import Method, MethodParams
from algorithms.common.episodes import Decision, EpisodeBatch
from envs.observations import action_progress
from tests.crash_once import first_claim


class FakeParams(MethodParams):
    ref_size: int = Field(8, ge=1)
    search_radius: int = Field(2, ge=0)
    c_max: int = Field(500, ge=1)
    fail: bool = False  # raise in train_iteration (an ordinary trial failure)
    crash_file: str = ""  # kill the process once (see the module docstring)


class FakeHierarchical(Method):
    name = "fake_hier"
    Params = FakeParams

    def begin(self, batch: EpisodeBatch, choice: Any) -> Any:
        return np.random.default_rng(batch.rng.integers(2**31))

    def decide(self, batch: EpisodeBatch, state: Any, choice: Any) -> Decision:
        core = batch.core
        prog = action_progress(core)
        actions = prog.argmax(axis=-1)
        noisy = state.random(actions.shape) < 1.0 / self.params.ref_size
        actions = np.where(noisy, state.integers(0, 5, actions.shape), actions)
        return Decision(actions=actions)

    def train_iteration(self) -> list[dict[str, float]]:
        if self.params.fail:
            raise RuntimeError("deliberate failure")
        if self.params.crash_file and first_claim(self.params.crash_file):
            os._exit(17)
        return super().train_iteration()

    def update(self, state: Any) -> dict[str, float]:
        return {"loss": 0.0}


FAKE_PATH = f"{__name__}:FakeHierarchical"


def register() -> None:
    """Make ``fake_hier`` a method name (in this process only)."""
    from algorithms import registry

    registry.register("fake_hier", FAKE_PATH)
