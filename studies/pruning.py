"""Pruning that waits until intermediate values predict final ones, and the measurement.

Issue #16: a median pruner deciding at one third of training on 10 evaluation episodes had
a rank correlation of 0.39 between its decision value and the final value, and pruned the
best configuration's own replicate. ``PredictivePruner`` prunes a trial at step ``s`` only
when all of these hold:

1. ``s >= warmup_step`` (a fixed fraction of training, ``--prune-warmup``, default 0.5);
2. at least ``n_startup`` complete trials reported a value at ``s``;
3. across those complete trials, Spearman's rank correlation between the value at ``s`` and
   the final value is at least ``min_rho`` (``--prune-min-rho``, default 0.7): the step's
   ranking is shown, on this study's own trials, to predict the final ranking;
4. the trial's *configuration* is below the median of the complete trials' values at
   ``s`` (Optuna's median rule, applied to configurations): its score is the mean of the
   trial's value at ``s`` and the final values of the configuration's complete replicates.
   For a first replicate this is the plain median rule; a later replicate of a
   configuration that did well is not pruned for one weak seed, which would leave the
   configuration without the replicates its mean needs (issue #16: the best
   configuration's own replicate was pruned).

The correlation is measured on complete trials only (pruned ones have no final value), a
survivor sample whose restricted range tends to *lower* the correlation, so the gate errs
on the side of not pruning. ``step_correlations`` gives the same numbers for the report.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import optuna
from optuna.pruners import BasePruner
from optuna.trial import FrozenTrial, TrialState
from scipy.stats import spearmanr

from envs.errors import BenchError

WARMUP = 0.5  # fraction of the training updates before pruning may act
MIN_RHO = 0.7  # rank correlation (value at the step vs final) required to prune
N_STARTUP = 5  # complete trials needed at a step before it may prune


def rank_correlation(x: Sequence[float], y: Sequence[float]) -> float:
    """Spearman's rho of two equal-length samples (ties get average ranks); NaN when fewer
    than 3 pairs or either sample is constant (the ranking carries no information)."""
    a, b = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if a.shape != b.shape or a.ndim != 1:
        raise BenchError(f"rank_correlation: samples must be 1-D of equal length, got {a.shape} and {b.shape}")
    keep = np.isfinite(a) & np.isfinite(b)
    a, b = a[keep], b[keep]
    if len(a) < 3 or np.ptp(a) == 0 or np.ptp(b) == 0:
        return math.nan
    return float(spearmanr(a, b).statistic)


def warmup_step(iterations: int, warmup: float) -> int:
    """First training update at which pruning may act: ceil(warmup * iterations), >= 1."""
    if not 0.0 <= warmup <= 1.0:
        raise BenchError(f"--prune-warmup must be in [0, 1], got {warmup}")
    return max(1, math.ceil(warmup * iterations - 1e-9))


def pairs_at(trials: Sequence[FrozenTrial], step: int) -> tuple[list[float], list[float]]:
    """(value at ``step``, final value) of the complete trials that reported ``step``."""
    at, final = [], []
    for t in trials:
        if t.state == TrialState.COMPLETE and step in t.intermediate_values and t.values:
            at.append(float(t.intermediate_values[step]))
            final.append(float(t.values[0]))
    return at, final


class PredictivePruner(BasePruner):
    """Median pruning gated by a warm-up and a measured rank correlation (module docstring).

    ``decision`` also returns the numbers behind the verdict, which the driver stores on a
    pruned trial (``prune_rho``, ``prune_n``, ``prune_median``) for the report.
    """

    def __init__(self, warmup_step: int, min_rho: float = MIN_RHO, n_startup: int = N_STARTUP) -> None:
        if not -1.0 <= min_rho <= 1.0:
            raise BenchError(f"--prune-min-rho must be in [-1, 1], got {min_rho}")
        self.warmup_step = int(warmup_step)
        self.min_rho = float(min_rho)
        self.n_startup = max(1, int(n_startup))

    def decision(self, study: optuna.Study, trial: FrozenTrial) -> tuple[bool, float, int, float]:
        """(prune?, rho at the step, complete trials behind it, median at the step)."""
        step = trial.last_step
        if step is None or step < self.warmup_step:
            return False, math.nan, 0, math.nan
        value = trial.intermediate_values[step]
        complete = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
        at, final = pairs_at(complete, step)
        if len(at) < self.n_startup:
            return False, math.nan, len(at), math.nan
        rho = rank_correlation(at, final)
        median = float(np.median(at))
        if not (rho >= self.min_rho):  # NaN (no ranking information) never prunes
            return False, rho, len(at), median
        return bool(configuration_score(complete, trial, value) < median), rho, len(at), median

    def prune(self, study: optuna.Study, trial: FrozenTrial) -> bool:
        return self.decision(study, trial)[0]


def configuration_score(complete: Sequence[FrozenTrial], trial: FrozenTrial, value: float) -> float:
    """Mean of ``value`` (the trial at the current step) and the final values of the complete
    trials with the same parameters (the configuration's other replicates)."""
    finals = [float(t.values[0]) for t in complete if t.params == trial.params and t.values]
    return float(np.mean([value, *finals]))


def step_correlations(intermediate: Sequence[Mapping[int, float]], finals: Sequence[float]) -> list[dict[str, float]]:
    """Per reported step: ``{"step", "n", "rho"}`` between the values at that step and the
    final values, over the given (complete) trials; the final step itself is left out."""
    steps = sorted({int(s) for iv in intermediate for s in iv})
    if steps:
        steps = steps[:-1]
    out = []
    for s in steps:
        pairs = [(float(iv[s]), float(f)) for iv, f in zip(intermediate, finals, strict=True) if s in iv]
        x = [p[0] for p in pairs]
        y = [p[1] for p in pairs]
        out.append({"step": s, "n": len(pairs), "rho": rank_correlation(x, y) if pairs else math.nan})
    return out
