"""Trials to Parquet, importances, and the best configuration as a grid file (runtime ~3 s)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import pandas as pd
import pytest

from envs.errors import BenchError
from studies.executors import SequentialExecutor
from studies.export import (
    MIN_IMPORTANCE_TRIALS,
    best_grid_snippet,
    importances,
    read_trials,
    trials_frame,
    write_trials,
)
from studies.objective import TrialSettings
from studies.runner import run_study
from studies.schedule import SearchPlan
from studies.space import search_space
from studies.storage import CONFIG_ATTR
from tests.studies.conftest import make_study

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


@pytest.fixture
def finished_study(tmp_path: Path, settings: TrialSettings):  # noqa: ANN201
    """Two replicates of 4 configurations (exhaustive plan), pruning off: 8 complete trials."""
    study = make_study(tmp_path, settings, name="exp", pruner="none")
    study.set_user_attr(CONFIG_ATTR, {**settings.model_dump(mode="json"), "seed": 0, "replicates": 2})
    space = search_space(overrides={"ref_size": [2, 32], "search_radius": [0, 3]})
    run_study(study, settings, space, 0, 8, SequentialExecutor(1), pruning=False,
              plan=SearchPlan.make("grid", space, 2, 0))
    return study


def test_export__trials_round_trip_through_parquet(finished_study, tmp_path: Path) -> None:  # noqa: ANN001
    frame = trials_frame(finished_study)
    path = write_trials(finished_study, tmp_path / "exp", {"warmup_step": 2})
    assert path == tmp_path / "exp" / "trials.parquet"
    back = read_trials(path)
    pd.testing.assert_frame_equal(back, frame)
    assert sorted(zip(frame["ref_size"], frame["search_radius"], frame["replicate"], strict=True)) == [
        (r, rad, k) for r in (2, 32) for rad in (0, 3) for k in (0, 1)]
    assert list(frame["state"]) == ["COMPLETE"] * 8
    assert frame["value"].notna().all() and (frame["last_step"] == 3).all()
    assert not list((tmp_path / "exp").glob(".*tmp"))  # atomic write left no temp file
    config = json.loads((tmp_path / "exp" / "study.json").read_text())
    assert config["warmup_step"] == 2 and config["replicates"] == 2 and config["study"] == "exp"


def test_export__best_snippet_is_the_best_mean_and_parses_as_a_grid_file(finished_study, tmp_path: Path) -> None:  # noqa: ANN001
    from bench.design.grid_files import load_grid_file

    frame = trials_frame(finished_study)
    means = frame.groupby(["ref_size", "search_radius"])["value"].mean()
    best = means.idxmax()
    text = best_grid_snippet(finished_study)
    data = tomllib.loads(text)
    assert (data["base"]["ref_size"], data["base"]["search_radius"]) == best
    assert f"mean objective {means.max():.4f} over 2 replicates" in text
    assert data["base"]["n_robots"] == 4 and data["base"]["method"] == "fake_hier"
    path = tmp_path / "best.toml"
    path.write_text(text)
    grid = load_grid_file(path)
    (cell,) = grid.cells
    assert (cell.ref_size, cell.search_radius) == best
    assert cell.params["batch_episodes"] == 4


def test_export__best_of_a_study_without_complete_trials_is_an_error(tmp_path: Path, settings: TrialSettings) -> None:
    with pytest.raises(BenchError, match="no complete trial"):
        best_grid_snippet(make_study(tmp_path, settings))


def test_importances__only_from_enough_trials_and_with_a_caveat(tmp_path: Path, settings: TrialSettings) -> None:
    study = make_study(tmp_path, settings, name="imp", pruner="none")
    space = search_space(overrides={"ref_size": [1, 2, 4, 8, 16, 32], "search_radius": [0, 3]})
    plan = SearchPlan.make("grid", space, 1, 0)
    run_study(study, settings, space, 0, MIN_IMPORTANCE_TRIALS - 1, SequentialExecutor(1), pruning=False, plan=plan)
    few = importances(study)
    assert few["importances"] == {} and f"need {MIN_IMPORTANCE_TRIALS}" in few["reason"]
    run_study(study, settings, space, 0, MIN_IMPORTANCE_TRIALS, SequentialExecutor(1), pruning=False, plan=plan)
    imp = importances(study)
    assert imp["reason"] is None
    assert set(imp["importances"]) <= {"ref_size", "search_radius"}
    assert sum(imp["importances"].values()) == pytest.approx(1.0)
    assert f"from {MIN_IMPORTANCE_TRIALS} complete trials" in imp["caveat"]
