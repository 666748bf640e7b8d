"""The search plan: exhaustive grid with balanced seed replicates, TPE with replicates
(runtime ~20 s: one 40-trial study of the fake method on the default 20-point space)."""
from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import optuna
import pytest
from optuna.trial import TrialState

from envs.errors import BenchError
from studies.cli import tune_study
from studies.executors import SequentialExecutor
from studies.objective import TrialSettings
from studies.runner import run_study
from studies.schedule import GRID_MAX, SearchPlan, point_key, replicate_seed, resolve_mode
from studies.space import distributions, search_space
from tests.studies.conftest import make_study


def _counts(study: optuna.Study) -> Counter[str]:
    return Counter(point_key(t.params) for t in study.get_trials(deepcopy=False)
                   if t.state in (TrialState.COMPLETE, TrialState.PRUNED))


def test_plan__grid_visits_every_point_before_any_second_replicate(tmp_path: Path, settings: TrialSettings) -> None:
    space = search_space(overrides={"ref_size": [2, 8, 32], "search_radius": [0, 2]})
    plan = SearchPlan.make("grid", space, 2, seed=3)
    study = make_study(tmp_path, settings, pruner="none")
    run_study(study, settings, space, 3, 6, SequentialExecutor(2), pruning=False, plan=plan)
    assert set(_counts(study).values()) == {1} and len(_counts(study)) == 6  # one round: all 6 once
    run_study(study, settings, space, 3, 12, SequentialExecutor(2), pruning=False, plan=plan)
    counts = _counts(study)
    assert len(counts) == 6 and set(counts.values()) == {2}
    trials = study.get_trials(deepcopy=False)
    # replicate r of every point trains with the same seed; replicates differ
    for t in trials:
        assert t.user_attrs["seed"] == replicate_seed(3, t.user_attrs["replicate"])
    assert {t.user_attrs["replicate"] for t in trials} == {0, 1}
    # the order is the seeded permutation, rerun-independent
    assert [point_key(t.params) for t in trials[:6]] == [point_key(p) for p in plan.points]


def test_plan__tpe_replicates_every_point_it_completes(tmp_path: Path, settings: TrialSettings) -> None:
    space = search_space()
    plan = SearchPlan.make("tpe", space, 2, seed=0)
    study = make_study(tmp_path, settings, pruner="none")
    run_study(study, settings, space, 0, 8, SequentialExecutor(1), pruning=False, plan=plan)
    trials = study.get_trials(deepcopy=False)
    per_point = Counter(point_key(t.params) for t in trials)
    last = point_key(trials[-1].params)  # the study may stop before the last proposal's replicate
    assert all(n >= 2 for key, n in per_point.items() if key != last), per_point
    for key in per_point:
        reps = sorted(t.user_attrs["replicate"] for t in trials if point_key(t.params) == key)
        assert reps == list(range(len(reps)))


def test_plan__a_waiting_requeued_trial_runs_before_anything_is_enqueued(settings: TrialSettings,
                                                                         tmp_path: Path) -> None:
    space = search_space(overrides={"ref_size": [2, 4]})
    plan = SearchPlan.make("grid", space, 2, seed=0)
    study = make_study(tmp_path, settings)
    study.enqueue_trial({"ref_size": 4, "search_radius": 3})
    assert plan.next_point(study.get_trials(deepcopy=False)) is None
    study.ask(distributions(space))
    nxt = plan.next_point(study.get_trials(deepcopy=False))
    assert nxt is not None and point_key(nxt[0]) != point_key({"ref_size": 4, "search_radius": 3})


def test_plan__modes_and_default_trials() -> None:
    assert resolve_mode("auto", search_space()) == "grid"
    assert resolve_mode("auto", search_space(c_max=True)) == ("grid" if 100 <= GRID_MAX else "tpe")
    assert SearchPlan.make("auto", search_space(), 2, 0).default_trials() == 40
    with pytest.raises(BenchError, match="unknown search 'random'"):
        resolve_mode("random", search_space())
    with pytest.raises(BenchError, match="--replicates must be >= 1"):
        SearchPlan.make("grid", search_space(), 0, 0)


def test_tune__the_20_point_space_gets_2_replicates_each_before_a_best(tmp_path: Path) -> None:
    """Done-when of issue #16: every point evaluated twice before a best is reported, and the
    report shows the rank correlation between pruning-time and final values."""
    opts = {"method": "fake_hier", "n_robots": 4, "horizon": 16, "episodes": 8, "eval_episodes": 5,
            "batch_episodes": 4, "eval_every": 1, "eval_chunk": 5, "report_chunks": 1}
    partial = tune_study("full", 39, opts, root=tmp_path, inline=True)
    assert partial.best is None and "19 of 20 configurations have 2 finished" in partial.best_reason
    res = tune_study("full", None, {}, root=tmp_path, inline=True)  # resume: default = 20 x 2
    assert res.summary.finished == 40 and res.best is not None
    study = optuna.load_study(study_name="full", storage=optuna.storages.JournalStorage(
        optuna.storages.journal.JournalFileBackend(str(tmp_path / "full" / "journal.log"))))
    counts = _counts(study)
    assert len(counts) == 20 and set(counts.values()) == {2}
    text = (tmp_path / "full" / "report" / "study.md").read_text()
    assert "Spearman rho" in text and "At the first update where pruning may act (1): rho = " in text
    assert json.loads((tmp_path / "full" / "study.json").read_text())["search_resolved"] == "grid"
