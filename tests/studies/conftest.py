"""Fixtures of the studies tests: the fake method, tiny settings, a local study."""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import optuna
import pytest

from algorithms import registry
from studies.objective import TrialSettings
from studies.runner import make_pruner
from studies.storage import open_storage, open_study
from tests.studies.fake_method import FAKE_PATH

optuna.logging.set_verbosity(optuna.logging.WARNING)


@pytest.fixture(autouse=True)
def fake_method() -> Iterator[str]:
    """Register ``fake_hier`` for the duration of a test."""
    registry.register("fake_hier", FAKE_PATH)
    yield "fake_hier"
    registry.unregister("fake_hier")


@pytest.fixture
def settings() -> TrialSettings:
    """4 robots on ``tiny``, 3 updates of 4 episodes, an evaluation after each update."""
    return TrialSettings.make(method="fake_hier", n_robots=4, horizon=16, episodes=12,
                              batch_episodes=4, eval_every=1, eval_episodes=10, eval_chunk=5)


def make_study(directory: Path, settings: TrialSettings, name: str = "s", seed: int = 0,
               pruner: str = "median") -> optuna.Study:
    store = open_storage(None, directory / name)
    return open_study(name, store, settings.directions, seed,
                      make_pruner(pruner, settings.multi_objective, settings.iterations))
