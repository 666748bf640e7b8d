"""The driver loop: reporting, pruning, crash repair, interruption, failures (runtime ~4 s)."""
from __future__ import annotations

import socket
import subprocess
import sys
import time
from pathlib import Path

import optuna
import pytest
from optuna.trial import TrialState

from envs.errors import BenchError
from studies.executors import SequentialExecutor
from studies.objective import TrialSettings
from studies.runner import run_study
from studies.schedule import replicate_seed
from studies.space import distributions, search_space
from studies.storage import LEASE_BEAT, LEASE_HOST, LEASE_PID, RETRY_OF
from tests.studies.conftest import make_study

GOOD = {"ref_size": 32, "search_radius": 2}
BAD = {"ref_size": 1, "search_radius": 2}  # every action random: far below the median
SPACE = search_space(overrides={"ref_size": [1, 32]})


def _states(study: optuna.Study) -> list[str]:
    return [t.state.name for t in study.get_trials(deepcopy=False)]


def test_runner__reports_each_segment_and_prunes_a_bad_trial_only_after_the_warmup(
        tmp_path: Path, settings: TrialSettings, monkeypatch: pytest.MonkeyPatch) -> None:
    calls = {"report": 0, "should_prune": 0}
    report, should_prune = optuna.trial.Trial.report, optuna.trial.Trial.should_prune

    def spy_report(self, value, step):  # noqa: ANN001, ANN202
        calls["report"] += 1
        return report(self, value, step)

    def spy_prune(self):  # noqa: ANN001, ANN202
        calls["should_prune"] += 1
        return should_prune(self)

    monkeypatch.setattr(optuna.trial.Trial, "report", spy_report)
    monkeypatch.setattr(optuna.trial.Trial, "should_prune", spy_prune)
    study = make_study(tmp_path, settings)  # 3 updates, warm-up 0.5: pruning from update 2
    ranked = [{"ref_size": r, "search_radius": 2} for r in (2, 4, 8, 16, 32)]
    for params in (*ranked, BAD):
        study.enqueue_trial(params)
    space = search_space(overrides={"ref_size": [1, 2, 4, 8, 16, 32]})
    logs: list[str] = []
    summary = run_study(study, settings, space, 0, 6, SequentialExecutor(1), log=logs.append)
    assert (summary.complete, summary.pruned, summary.finished) == (5, 1, 6)
    trials = study.get_trials(deepcopy=False)
    assert [t.state for t in trials] == [TrialState.COMPLETE] * 5 + [TrialState.PRUNED]
    assert all(sorted(t.intermediate_values) == [1, 2, 3] for t in trials[:5])
    assert sorted(trials[5].intermediate_values) == [1, 2]  # not pruned at update 1 (warm-up)
    assert trials[5].user_attrs["pruned_at_step"] == 2
    assert trials[5].user_attrs["prune_rho"] >= 0.7 and trials[5].user_attrs["prune_n"] == 5
    # 3 reports per complete trial + 2; the pruner is asked after every non-final segment
    assert calls == {"report": 17, "should_prune": 12}
    assert "pruned" in summary.reason()
    pruned_line = next(m for m in logs if "pruned at step" in m)
    assert "rank correlation" in pruned_line and "[6/6 finished, 0 running" in pruned_line
    assert "configuration mean" not in pruned_line  # a first replicate is judged on its own value


def test_runner__no_pruning_gives_all_complete_and_says_why(tmp_path: Path, settings: TrialSettings) -> None:
    study = make_study(tmp_path, settings, pruner="none")
    for params in (GOOD, GOOD, GOOD, BAD):
        study.enqueue_trial(params)
    summary = run_study(study, settings, SPACE, 0, 4, SequentialExecutor(2), pruning=False)
    assert summary.complete == 4 and summary.pruned == 0
    assert "pruning off" in summary.reason()


def test_runner__multi_objective_tells_success_and_return_without_reports(
        tmp_path: Path, settings: TrialSettings) -> None:
    multi = settings.model_copy(update={"objectives": "success,return"})
    study = make_study(tmp_path, multi)
    summary = run_study(study, multi, SPACE, 0, 2, SequentialExecutor(2))
    assert summary.complete == 2
    for t in study.get_trials(deepcopy=False):
        assert t.values == [t.user_attrs["success_rate"], t.user_attrs["team_return"]]
        assert t.intermediate_values == {}


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_runner__trials_left_running_by_a_crash_are_failed_requeued_and_finished(
        tmp_path: Path, settings: TrialSettings) -> None:
    study = make_study(tmp_path, settings)
    dists = distributions(search_space())
    study.enqueue_trial({"ref_size": 4, "search_radius": 1})
    no_lease = study.ask(dists)  # crashed before it took its lease
    study.enqueue_trial({"ref_size": 16, "search_radius": 3})
    dead = study.ask(dists)
    for key, val in {LEASE_HOST: socket.gethostname(), LEASE_PID: _dead_pid(),
                     LEASE_BEAT: time.time()}.items():
        dead.set_user_attr(key, val)
    alive = study.ask(dists)  # a live driver on another machine: left alone
    for key, val in {LEASE_HOST: "elsewhere", LEASE_PID: 1, LEASE_BEAT: time.time()}.items():
        alive.set_user_attr(key, val)

    summary = run_study(study, settings, search_space(), 7, 4, SequentialExecutor(1))

    assert summary.recovered == [0, 1]
    trials = study.get_trials(deepcopy=False)
    assert [t.state for t in trials[:3]] == [TrialState.FAIL, TrialState.FAIL, TrialState.RUNNING]
    retries = {t.user_attrs[RETRY_OF]: t for t in trials if RETRY_OF in t.user_attrs}
    assert sorted(retries) == [0, 1]
    for number, crashed in ((0, no_lease), (1, dead)):
        assert retries[number].state == TrialState.COMPLETE
        assert retries[number].params == crashed.params
        assert retries[number].user_attrs["seed"] == replicate_seed(7, 0)  # the crashed one's replicate
    assert summary.finished == 3 and summary.running_elsewhere == 1  # 3 + 1 running = 4


def test_runner__a_stale_remote_lease_is_recovered(tmp_path: Path, settings: TrialSettings) -> None:
    study = make_study(tmp_path, settings)
    stale = study.ask(distributions(search_space()))
    for key, val in {LEASE_HOST: "elsewhere", LEASE_PID: 1, LEASE_BEAT: time.time() - 3600}.items():
        stale.set_user_attr(key, val)
    summary = run_study(study, settings, search_space(), 0, 1, SequentialExecutor(1))
    assert summary.recovered == [0] and summary.finished == 1


class InterruptAfter(SequentialExecutor):
    """Raises KeyboardInterrupt on the ``n``-th wait, like Ctrl-C during a trial."""

    def __init__(self, capacity: int, n: int) -> None:
        super().__init__(capacity)
        self.n = n

    def wait(self, timeout: float | None = None):  # noqa: ANN201
        self.n -= 1
        if self.n == 0:
            raise KeyboardInterrupt
        return super().wait(timeout)


def test_runner__interrupted_study_resumes_to_the_requested_count_with_none_lost(
        tmp_path: Path, settings: TrialSettings) -> None:
    study = make_study(tmp_path, settings)
    with pytest.raises(KeyboardInterrupt):
        run_study(study, settings, search_space(), 0, 5, InterruptAfter(2, n=8))
    first = study.get_trials(deepcopy=False)
    interrupted = [t for t in first if t.state == TrialState.FAIL]
    assert len(interrupted) == 2 and not [t for t in first if t.state == TrialState.RUNNING]
    done_before = sum(t.state in (TrialState.COMPLETE, TrialState.PRUNED) for t in first)
    assert done_before >= 1

    study = make_study(tmp_path, settings)  # a new process opening the same journal
    summary = run_study(study, settings, search_space(), 0, 5, SequentialExecutor(2))
    trials = study.get_trials(deepcopy=False)
    assert summary.finished == 5 and summary.recovered == []
    finished = [t for t in trials if t.state in (TrialState.COMPLETE, TrialState.PRUNED)]
    assert len(finished) == 5
    assert {t.number for t in first if t.state in (TrialState.COMPLETE, TrialState.PRUNED)} <= {
        t.number for t in finished}  # nothing finished before is lost
    retried = {t.user_attrs.get(RETRY_OF) for t in finished}
    assert {t.number for t in interrupted} <= retried  # every interrupted trial re-run


def test_runner__repeated_failures_stop_the_study_with_the_error(tmp_path: Path, settings: TrialSettings) -> None:
    failing = settings.model_copy(update={"params": {"fail": True}})
    study = make_study(tmp_path, failing)
    with pytest.raises(BenchError, match="3 trials failed in a row; last error: RuntimeError: deliberate failure"):
        run_study(study, failing, search_space(), 0, 5, SequentialExecutor(1))
    assert _states(study).count("FAIL") == 3


def test_runner__a_study_that_already_holds_n_trials_runs_nothing(tmp_path: Path, settings: TrialSettings) -> None:
    study = make_study(tmp_path, settings)
    run_study(study, settings, search_space(), 0, 2, SequentialExecutor(2))
    summary = run_study(study, settings, search_space(), 0, 2, SequentialExecutor(2))
    assert summary.started == 0 and summary.finished == 2


def test_runner__records_the_filters_rates_beside_the_success_rate(
        tmp_path: Path, settings: TrialSettings, monkeypatch: pytest.MonkeyPatch) -> None:
    """A trial of a method with a safety filter keeps its final evaluation's fallback and
    correction rates (trials frame, log line, study page); one without keeps NaN and the
    page shows no such column."""
    from studies import objective
    from studies.export import trials_frame
    from studies.report_page import study_page

    study = make_study(tmp_path, settings, pruner="none")
    study.enqueue_trial(GOOD)
    run_study(study, settings, SPACE, 0, 1, SequentialExecutor(1), pruning=False)
    frame = trials_frame(study)
    assert frame[["fallback_rate", "correction_rate"]].isna().all().all()  # the fake method has no filter
    assert "fallback" not in study_page(frame, {}, {}, {}).markdown()

    monkeypatch.setattr(objective, "filter_rates", lambda rows: (0.25, 0.5))
    study = make_study(tmp_path / "filtered", settings, pruner="none")
    study.enqueue_trial(GOOD)
    logs: list[str] = []
    run_study(study, settings, SPACE, 0, 1, SequentialExecutor(1), pruning=False, log=logs.append)
    frame = trials_frame(study)
    assert frame[["fallback_rate", "correction_rate"]].iloc[0].tolist() == [0.25, 0.5]
    assert ", fallback 25.0%, correction 50.0% (" in next(m for m in logs if "complete" in m)
    page = study_page(frame, {}, {"replicates": 1}, {}).markdown()
    assert "(fallback 25.0%) (corrections 50.0%)" in page and "| fallback | corrections |" in page
    assert "| 25.0% | 50.0% | yes |" in page  # the configuration's row: its rates, then eligible


def test_study_page__percentages_leave_a_missing_rate_blank() -> None:
    from studies.report_page import _pct

    assert (_pct(0.25), _pct(float("nan")), _pct(None)) == ("25.0%", "", "")


def test_runner__a_pruned_later_replicate_logs_the_configuration_mean_that_was_judged(
        tmp_path: Path, settings: TrialSettings) -> None:
    study = make_study(tmp_path, settings)
    ranked = [{"ref_size": r, "search_radius": 2} for r in (2, 4, 8, 16, 32)]
    for params in (*ranked, BAD):
        study.enqueue_trial(params)
    space = search_space(overrides={"ref_size": [1, 2, 4, 8, 16, 32]})
    run_study(study, settings, space, 0, 6, SequentialExecutor(1), pruning=False)
    study.enqueue_trial(BAD)  # its second replicate: judged with the first one's final value
    logs: list[str] = []
    run_study(study, settings, space, 0, 7, SequentialExecutor(1), log=logs.append)
    line = next(m for m in logs if "pruned at step" in m)
    first = study.get_trials(deepcopy=False)[5]
    assert first.state == TrialState.COMPLETE and first.params == BAD
    assert "(configuration mean " in line and "with 1 complete replicate(s)) below the median" in line
