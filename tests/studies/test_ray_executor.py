"""Trials as Ray actors: a worker process that dies is re-queued and finished (runtime ~30 s)."""
from __future__ import annotations

from pathlib import Path

import pytest
from optuna.trial import TrialState

from studies.objective import TrialSettings
from studies.runner import run_study
from studies.space import search_space
from studies.storage import RETRY_OF
from tests.studies.conftest import make_study


@pytest.mark.slow
def test_ray_executor__a_killed_worker_is_requeued_and_the_study_finishes(
        tmp_path: Path, settings: TrialSettings) -> None:
    from studies.executors import RayExecutor

    crash_file = tmp_path / "crashed-once"
    crashing = settings.model_copy(update={"params": {"crash_file": str(crash_file)}})
    study = make_study(tmp_path, crashing)
    log: list[str] = []
    summary = run_study(study, crashing, search_space(), 0, 3, RayExecutor(2), log=log.append)
    assert crash_file.exists()
    assert summary.finished == 3
    trials = study.get_trials(deepcopy=False)
    failed = [t for t in trials if t.state == TrialState.FAIL]
    assert len(failed) == 1 and "worker died" in failed[0].user_attrs["error"]
    retry = next(t for t in trials if t.user_attrs.get(RETRY_OF) == failed[0].number)
    assert retry.state in (TrialState.COMPLETE, TrialState.PRUNED)
    assert retry.params == failed[0].params
    assert any("lost its worker" in line for line in log)
