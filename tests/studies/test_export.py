"""Trials to Parquet, importances, and the best configuration as a grid file (runtime ~3 s)."""
from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest

from envs.errors import BenchError
from studies.executors import SequentialExecutor
from studies.export import (
    best_grid_snippet,
    importances,
    read_trials,
    trials_frame,
    write_trials,
)
from studies.objective import TrialSettings
from studies.runner import run_study
from studies.space import search_space
from studies.storage import CONFIG_ATTR
from tests.studies.conftest import make_study

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


@pytest.fixture
def finished_study(tmp_path: Path, settings: TrialSettings):  # noqa: ANN201
    study = make_study(tmp_path, settings, name="exp")
    study.set_user_attr(CONFIG_ATTR, {**settings.model_dump(mode="json"), "seed": 0})
    for params in ({"ref_size": 32, "search_radius": 1}, {"ref_size": 2, "search_radius": 3},
                   {"ref_size": 8, "search_radius": 0}, {"ref_size": 1, "search_radius": 2}):
        study.enqueue_trial(params)
    space = search_space(overrides={"ref_size": [1, 2, 8, 32]})
    run_study(study, settings, space, 0, 4, SequentialExecutor(1))
    return study


def test_export__trials_round_trip_through_parquet(finished_study, tmp_path: Path) -> None:  # noqa: ANN001
    frame = trials_frame(finished_study)
    path = write_trials(finished_study, tmp_path / "exp")
    assert path == tmp_path / "exp" / "trials.parquet"
    back = read_trials(path)
    pd.testing.assert_frame_equal(back, frame)
    assert list(frame["ref_size"]) == [32, 2, 8, 1]
    assert list(frame["state"]) == ["COMPLETE", "COMPLETE", "COMPLETE", "PRUNED"]
    comp = frame[frame["state"] == "COMPLETE"]
    assert comp["value"].notna().all() and (comp["last_step"] == 3).all()
    assert not list((tmp_path / "exp").glob(".*tmp"))  # atomic write left no temp file


def test_export__best_snippet_parses_as_a_grid_file(finished_study, tmp_path: Path) -> None:  # noqa: ANN001
    from bench.grid_files import load_grid_file

    text = best_grid_snippet(finished_study)
    data = tomllib.loads(text)
    best = finished_study.best_trial
    assert data["base"]["ref_size"] == best.params["ref_size"]
    assert data["base"]["search_radius"] == best.params["search_radius"]
    assert data["base"]["n_robots"] == 4 and data["base"]["method"] == "fake_hier"
    path = tmp_path / "best.toml"
    path.write_text(text)
    grid = load_grid_file(path)
    (cell,) = grid.cells
    assert (cell.ref_size, cell.search_radius) == (best.params["ref_size"], best.params["search_radius"])
    assert cell.params["batch_episodes"] == 4


def test_export__best_of_a_study_without_complete_trials_is_an_error(tmp_path: Path, settings: TrialSettings) -> None:
    with pytest.raises(BenchError, match="no complete trial"):
        best_grid_snippet(make_study(tmp_path, settings))


def test_importances__computed_with_enough_trials_else_a_reason(finished_study, tmp_path: Path,  # noqa: ANN001
                                                                settings: TrialSettings) -> None:
    imp = importances(finished_study)
    assert imp["reason"] is None
    assert set(imp["importances"]) <= {"ref_size", "search_radius"}
    assert sum(imp["importances"].values()) == pytest.approx(1.0)
    empty = importances(make_study(tmp_path, settings, name="empty"))
    assert empty["importances"] == {} and "too few trials" in empty["reason"]
