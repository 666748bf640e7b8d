"""The driver loop: the driver owns the study (ask/tell); executors only run segments.

``run_study`` keeps up to ``executor.capacity`` trials running. For each one it takes the
next configuration from the ``SearchPlan`` (studies/schedule.py: the least-replicated grid
point, enqueued, or TPE's proposal), asks the study for it (``study.ask`` with the fixed
categorical space), starts a worker with the seed of the trial's replicate index, and for
every streamed ``Segment`` it reports the intermediate value (``trial.report``) and asks
the pruner (``trial.should_prune``; studies/pruning.py) before letting the worker train
on: pruning happens on the driver, as ask/tell requires, and a pruned worker is stopped
at once. ``n_trials`` counts finished (COMPLETE or PRUNED) trials of the whole
study, so a rerun after an interruption tops the study up to the requested number.
Multi-objective studies cannot prune (Optuna); their segments are only recorded.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import optuna
from optuna.trial import Trial, TrialState

from envs.errors import BenchError
from studies.executors import Outcome
from studies.objective import Segment, TrialSettings, TrialSpec, eval_seed
from studies.progress import TuneSnapshot
from studies.pruning import MIN_RHO, WARMUP, PredictivePruner, configuration_score, warmup_step
from studies.schedule import SearchPlan, replicate_seed, trial_replicate
from studies.space import distributions
from studies.storage import LEASE_BEAT, REPLICATE, lease_attrs, recover_orphans, requeue
from studies.trial_columns import FILTER_RATES

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
            return (f"{self.pruned} trial(s) pruned: after the warm-up, at a step whose values "
                    "rank-correlate with the final ones, they fell below the median of the "
                    "complete trials at that step")
        return ("all trials complete: pruning waits for the warm-up, 5 complete trials and a "
                "rank correlation >= the threshold between a step's values and the final ones "
                "(see the study report), and then for a trial below the median")


def make_pruner(kind: str, multi_objective: bool, iterations: int = 1, warmup: float = WARMUP,
                min_rho: float = MIN_RHO) -> optuna.pruners.BasePruner:
    """``median``: ``PredictivePruner`` (median rule after ``warmup`` of the ``iterations``
    training updates, gated by a rank correlation >= ``min_rho``), or ``none``."""
    if kind == "none" or multi_objective:
        return optuna.pruners.NopPruner()
    if kind == "median":
        return PredictivePruner(warmup_step(iterations, warmup), min_rho=min_rho)
    raise BenchError(f"unknown pruner {kind!r}; choose median or none")


def preflight(settings: TrialSettings, space: Mapping[str, Sequence[int]]) -> None:
    """Fail fast on a configuration no trial could run (bad layout, too many robots, a
    value the method rejects): every extreme of the space must make a valid cell."""
    for pick in (min, max):
        settings.cell({name: pick(choices) for name, choices in space.items()}, seed=0)


def run_study(study: optuna.Study, settings: TrialSettings, space: Mapping[str, Sequence[int]],
              study_seed: int, n_trials: int, executor: Executor, pruning: bool = True,
              log: Callable[[str], None] = lambda _msg: None,
              heartbeat_s: float = HEARTBEAT_S, plan: SearchPlan | None = None,
              progress: Callable[[TuneSnapshot], None] = lambda _s: None) -> RunSummary:
    """Run trials until the study holds ``n_trials`` finished ones; see the module doc.

    ``plan`` defaults to TPE without replicates; ``progress`` gets a snapshot after every
    finished trial (and one at the start).
    """
    t0 = time.perf_counter()
    plan = plan or SearchPlan.make("tpe", space, 1, study_seed)
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
    finished_before = _finished(study)

    def snapshot() -> TuneSnapshot:
        done = _finished(study)
        return TuneSnapshot(n_trials, done, done - finished_before, len(running), time.perf_counter() - t0)

    progress(snapshot())
    try:
        while True:
            while len(running) < executor.capacity and _occupied(study) < n_trials:
                nxt = plan.next_point(study.get_trials(deepcopy=False))
                if nxt is not None:
                    study.enqueue_trial(nxt[0], user_attrs={REPLICATE: nxt[1]})
                trial = study.ask(dists)
                for key, val in lease_attrs().items():
                    trial.set_user_attr(key, val)
                replicate = trial_replicate(study, trial)
                seed = replicate_seed(study_seed, replicate)
                trial.set_user_attr(REPLICATE, replicate)
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
                log(f"trial {trial.number} started: {_fmt(trial.params)} (replicate {replicate})")
            if not running:
                break
            for number, outcome in executor.wait(timeout=heartbeat_s):
                trial = running[number]
                if isinstance(outcome, Segment):
                    failures = 0
                    if _on_segment(study, trial, outcome, executor, running, pruning, log, snapshot):
                        progress(snapshot())
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
                running: dict[int, Trial], pruning: bool, log: Callable[[str], None],
                snapshot: Callable[[], TuneSnapshot]) -> bool:
    """Report one segment; finish, prune or continue the trial (True: it finished)."""
    trial.set_user_attr(LEASE_BEAT, time.time())
    trial.set_user_attr("success_rate", seg.success_rate)
    trial.set_user_attr("team_return", seg.team_return)
    for key in FILTER_RATES:  # a method with a safety filter only
        if not math.isnan(getattr(seg, key)):
            trial.set_user_attr(key, getattr(seg, key))
    trial.set_user_attr("episodes", seg.episodes)
    trial.set_user_attr("wall_s", float(trial.user_attrs.get("wall_s", 0.0)) + seg.wall_s)
    if len(study.directions) == 1:
        trial.report(seg.values[0], seg.step)
    if seg.done:
        running.pop(trial.number)
        executor.stop(trial.number)
        study.tell(trial, list(seg.values))
        rates = "".join(f", {key.removesuffix('_rate')} {getattr(seg, key):.1%}" for key in FILTER_RATES
                        if not math.isnan(getattr(seg, key)))
        log(f"trial {trial.number} complete: success {seg.success_rate:.3f}, "
            f"return {seg.team_return:.1f}{rates} ({_fmt(trial.params)}) {snapshot().line()}")
        return True
    if pruning and trial.should_prune():
        running.pop(trial.number)
        executor.stop(trial.number)
        trial.set_user_attr("pruned_at_step", seg.step)
        why = "below the median"
        if isinstance(study.pruner, PredictivePruner):
            frozen = _frozen(study, trial.number)
            _, rho, n, median = study.pruner.decision(study, frozen)
            trial.set_user_attr("prune_rho", rho)
            trial.set_user_attr("prune_n", n)
            trial.set_user_attr("prune_median", median)
            why = f"below the median {median:.3f} of {n} complete trials; rank correlation {rho:.2f}"
            complete = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
            others = sum(t.params == frozen.params for t in complete)
            if others:  # a later replicate: the configuration's mean is what was judged
                score = configuration_score(complete, frozen, seg.values[0])
                why = f"(configuration mean {score:.3f} with {others} complete replicate(s)) {why}"
        study.tell(trial, state=TrialState.PRUNED)
        log(f"trial {trial.number} pruned at step {seg.step}: objective {seg.values[0]:.3f} "
            f"{why} ({_fmt(trial.params)}) {snapshot().line()}")
        return True
    executor.advance(trial.number)
    return False


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


def _finished(study: optuna.Study) -> int:
    return len(study.get_trials(deepcopy=False, states=FINISHED))


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
