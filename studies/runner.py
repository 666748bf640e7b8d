"""The driver loop: the driver owns the study (ask/tell); executors only run segments.

``run_study`` keeps up to ``executor.capacity`` trials running. For each one it asks the
study for parameters (``study.ask`` with the fixed categorical space), starts a worker,
and for every streamed ``Segment`` it reports the intermediate value (``trial.report``)
and asks the pruner (``trial.should_prune``, median by default) before letting the worker
train on: pruning happens on the driver, as ask/tell requires, and a pruned worker is
stopped at once. ``n_trials`` counts finished (COMPLETE or PRUNED) trials of the whole
study, so a rerun after an interruption tops the study up to the requested number.
Multi-objective studies cannot prune (Optuna); their segments are only recorded.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import optuna
from optuna.trial import Trial, TrialState

from envs.errors import BenchError
from studies.executors import Outcome
from studies.objective import Segment, TrialSettings, TrialSpec, eval_seed, trial_seed
from studies.space import distributions
from studies.storage import LEASE_BEAT, RETRY_OF, lease_attrs, recover_orphans, requeue

FINISHED = (TrialState.COMPLETE, TrialState.PRUNED)
HEARTBEAT_S = 60.0
MAX_CONSECUTIVE_FAILURES = 3


class Executor(Protocol):
    capacity: int

    def start(self, key: int, spec: TrialSpec) -> None: ...
    def advance(self, key: int) -> None: ...
    def stop(self, key: int) -> None: ...
    def wait(self, timeout: float | None = None) -> list[tuple[int, Outcome]]: ...
    def close(self) -> None: ...


@dataclass
class RunSummary:
    """What one invocation did, and the study's totals afterwards."""

    requested: int
    complete: int = 0  # study totals after the run
    pruned: int = 0
    failed: int = 0
    running_elsewhere: int = 0
    recovered: list[int] = field(default_factory=list)  # orphans re-queued at start
    started: int = 0  # trials this run launched
    wall_s: float = 0.0
    pruning: bool = True

    @property
    def finished(self) -> int:
        return self.complete + self.pruned

    def reason(self) -> str:
        """Why the study looks the way it does (shown by the CLI)."""
        if not self.pruning:
            return "pruning off (multi-objective studies cannot prune, or --pruner none)"
        if self.pruned:
            return (f"{self.pruned} trial(s) pruned: intermediate success fell below the median "
                    "of earlier complete trials at the same step")
        return ("all trials complete: none fell below the median of earlier complete trials "
                "at the same step (the median pruner waits for 3 complete trials)")


def make_pruner(kind: str, multi_objective: bool) -> optuna.pruners.BasePruner:
    """``median`` (default: 3 start-up trials, no warm-up) or ``none``."""
    if kind == "none" or multi_objective:
        return optuna.pruners.NopPruner()
    if kind == "median":
        return optuna.pruners.MedianPruner(n_startup_trials=3, n_warmup_steps=0)
    raise BenchError(f"unknown pruner {kind!r}; choose median or none")


def preflight(settings: TrialSettings, space: Mapping[str, Sequence[int]]) -> None:
    """Fail fast on a configuration no trial could run (bad layout, too many robots, a
    value the method rejects): every extreme of the space must make a valid cell."""
    for pick in (min, max):
        settings.cell({name: pick(choices) for name, choices in space.items()}, seed=0)


def run_study(study: optuna.Study, settings: TrialSettings, space: Mapping[str, Sequence[int]],
              study_seed: int, n_trials: int, executor: Executor, pruning: bool = True,
              log: Callable[[str], None] = lambda _msg: None,
              heartbeat_s: float = HEARTBEAT_S) -> RunSummary:
    """Run trials until the study holds ``n_trials`` finished ones; see the module doc."""
    t0 = time.perf_counter()
    pruning = pruning and not settings.multi_objective
    summary = RunSummary(requested=n_trials, pruning=pruning)
    summary.recovered = recover_orphans(study)
    for number in summary.recovered:
        log(f"trial {number} was left RUNNING by a crashed driver: marked FAIL and re-queued")
    dists = distributions(space)
    e_seed = eval_seed(study_seed)
    running: dict[int, Trial] = {}
    failures = 0
    last_beat = time.time()
    try:
        while True:
            while len(running) < executor.capacity and _occupied(study) < n_trials:
                trial = study.ask(dists)
                for key, val in lease_attrs().items():
                    trial.set_user_attr(key, val)
                root = int(trial.user_attrs.get(RETRY_OF, trial.number))
                seed = trial_seed(study_seed, root)
                trial.set_user_attr("seed", seed)
                try:
                    spec = settings.spec(trial.params, seed, e_seed)
                except BenchError as exc:
                    trial.set_user_attr("error", str(exc))
                    study.tell(trial, state=TrialState.FAIL)
                    raise
                trial.set_user_attr("cell_id", spec.cell_id)
                running[trial.number] = trial
                executor.start(trial.number, spec)
                summary.started += 1
                log(f"trial {trial.number} started: {_fmt(trial.params)}")
            if not running:
                break
            for number, outcome in executor.wait(timeout=heartbeat_s):
                trial = running[number]
                if isinstance(outcome, Segment):
                    failures = 0
                    _on_segment(study, trial, outcome, executor, running, pruning, log)
                    continue
                running.pop(number)
                executor.stop(number)
                if outcome.crashed:
                    log(f"trial {number} lost its worker ({outcome.message}); re-queued")
                    requeue(study, _frozen(study, number), outcome.message)
                    continue
                trial.set_user_attr("error", outcome.message)
                study.tell(trial, state=TrialState.FAIL)
                log(f"trial {number} failed: {outcome.message}")
                failures += 1
                if outcome.user_error:
                    raise BenchError(outcome.message)
                if failures >= MAX_CONSECUTIVE_FAILURES:
                    raise BenchError(f"{failures} trials failed in a row; last error: {outcome.message}")
            if time.time() - last_beat > heartbeat_s / 2:
                last_beat = time.time()
                for trial in running.values():
                    trial.set_user_attr(LEASE_BEAT, last_beat)
    except KeyboardInterrupt:
        n_running = len(running)
        _abandon(study, running, executor, "interrupted by the user; re-queued")
        log(f"interrupted: {n_running} running trial(s) marked FAIL and re-queued; "
            "rerun the same command to resume")
        raise
    except BaseException:
        _abandon(study, running, executor, "driver stopped on an error; re-queued")
        raise
    finally:
        executor.close()
    _totals(study, summary)
    summary.wall_s = time.perf_counter() - t0
    return summary


def _on_segment(study: optuna.Study, trial: Trial, seg: Segment, executor: Executor,
                running: dict[int, Trial], pruning: bool, log: Callable[[str], None]) -> None:
    """Report one segment; finish, prune or continue the trial."""
    trial.set_user_attr(LEASE_BEAT, time.time())
    trial.set_user_attr("success_rate", seg.success_rate)
    trial.set_user_attr("team_return", seg.team_return)
    trial.set_user_attr("episodes", seg.episodes)
    trial.set_user_attr("wall_s", float(trial.user_attrs.get("wall_s", 0.0)) + seg.wall_s)
    if len(study.directions) == 1:
        trial.report(seg.values[0], seg.step)
    if seg.done:
        running.pop(trial.number)
        executor.stop(trial.number)
        study.tell(trial, list(seg.values))
        log(f"trial {trial.number} complete: success {seg.success_rate:.3f}, "
            f"return {seg.team_return:.1f} ({_fmt(trial.params)})")
    elif pruning and trial.should_prune():
        running.pop(trial.number)
        executor.stop(trial.number)
        trial.set_user_attr("pruned_at_step", seg.step)
        study.tell(trial, state=TrialState.PRUNED)
        log(f"trial {trial.number} pruned at step {seg.step}: success {seg.success_rate:.3f} "
            f"below the median ({_fmt(trial.params)})")
    else:
        executor.advance(trial.number)


def _abandon(study: optuna.Study, running: dict[int, Trial], executor: Executor, reason: str) -> None:
    """Re-queue trials this driver can no longer finish (interrupt or driver error)."""
    frozen = {t.number: t for t in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,))}
    for number in list(running):
        executor.stop(number)
        if number in frozen:
            requeue(study, frozen[number], reason)
    running.clear()


def _frozen(study: optuna.Study, number: int) -> optuna.trial.FrozenTrial:
    return next(t for t in study.get_trials(deepcopy=False) if t.number == number)


def _occupied(study: optuna.Study) -> int:
    """Finished trials plus trials running anywhere (other drivers included)."""
    return len(study.get_trials(deepcopy=False, states=(*FINISHED, TrialState.RUNNING)))


def _totals(study: optuna.Study, summary: RunSummary) -> None:
    trials = study.get_trials(deepcopy=False)
    summary.complete = sum(t.state == TrialState.COMPLETE for t in trials)
    summary.pruned = sum(t.state == TrialState.PRUNED for t in trials)
    summary.failed = sum(t.state == TrialState.FAIL for t in trials)
    summary.running_elsewhere = sum(t.state == TrialState.RUNNING for t in trials)


def _fmt(params: Mapping[str, Any]) -> str:
    return ", ".join(f"{k}={v}" for k, v in params.items())
