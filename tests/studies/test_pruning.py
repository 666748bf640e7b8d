"""Rank correlation by hand, and the pruner's warm-up and correlation gate (runtime ~1 s)."""
from __future__ import annotations

import math

import optuna
import pytest
from optuna.distributions import CategoricalDistribution
from optuna.trial import TrialState, create_trial

from envs.errors import BenchError
from studies.pruning import PredictivePruner, rank_correlation, step_correlations, warmup_step

DIST = {"ref_size": CategoricalDistribution([1, 2, 4, 8, 16, 32])}


def test_rank_correlation__by_hand_with_ties() -> None:
    # ranks x (1, 3, 2), y (1, 2, 3): d = (0, 1, -1), rho = 1 - 6 * 2 / (3 * 8) = 0.5
    assert rank_correlation([0.2, 0.4, 0.3], [0.5, 0.7, 0.9]) == pytest.approx(0.5)
    assert rank_correlation([1, 2, 3, 4], [40, 30, 20, 10]) == pytest.approx(-1.0)
    # ties: x ranks (1.5, 1.5, 3, 4), y ranks (1, 2, 3, 4); Pearson of the ranks
    xr, yr = [1.5, 1.5, 3, 4], [1, 2, 3, 4]
    mx, my = sum(xr) / 4, sum(yr) / 4
    num = sum((a - mx) * (b - my) for a, b in zip(xr, yr, strict=True))
    den = math.sqrt(sum((a - mx) ** 2 for a in xr) * sum((b - my) ** 2 for b in yr))
    assert rank_correlation([0.1, 0.1, 0.5, 0.9], [1, 2, 3, 4]) == pytest.approx(num / den)
    assert math.isnan(rank_correlation([0.3, 0.3, 0.3], [1, 2, 3]))  # constant: no ranking
    assert math.isnan(rank_correlation([1, 2], [1, 2]))  # too few pairs
    with pytest.raises(BenchError, match="equal length"):
        rank_correlation([1, 2, 3], [1, 2])


def test_step_correlations__per_step_leaving_out_the_final_one() -> None:
    inter = [{1: 0.2, 2: 0.5, 3: 0.5}, {1: 0.4, 2: 0.7, 3: 0.7}, {1: 0.3, 2: 0.9, 3: 0.9}]
    rows = step_correlations(inter, [0.5, 0.7, 0.9])
    assert [r["step"] for r in rows] == [1, 2] and [r["n"] for r in rows] == [3, 3]
    assert rows[0]["rho"] == pytest.approx(0.5) and rows[1]["rho"] == pytest.approx(1.0)


def test_warmup_step__is_a_ceiling_fraction_of_training() -> None:
    assert warmup_step(6, 0.5) == 3 and warmup_step(3, 0.5) == 2 and warmup_step(10, 0.0) == 1
    assert warmup_step(6, 1 / 3) == 2
    with pytest.raises(BenchError, match="--prune-warmup"):
        warmup_step(6, 1.2)


def _study(finals: list[float], at: dict[int, list[float]], pruner: PredictivePruner) -> optuna.Study:
    """Complete trials with final values ``finals`` and intermediate values ``at[step]``."""
    study = optuna.create_study(direction="maximize", pruner=pruner)
    for i, final in enumerate(finals):
        study.add_trial(create_trial(
            state=TrialState.COMPLETE, value=final, params={"ref_size": 2}, distributions=DIST,
            intermediate_values={s: vals[i] for s, vals in at.items()}))
    return study


def _running(study: optuna.Study, values: dict[int, float]) -> optuna.trial.FrozenTrial:
    trial = study.ask(DIST)
    for step, v in values.items():
        trial.report(v, step)
    return next(t for t in study.get_trials(deepcopy=False) if t.number == trial.number)


FINALS = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
PREDICTIVE = {1: [0.6, 0.1, 0.5, 0.2, 0.4, 0.3],  # step 1: unrelated to the final ranking
              2: [0.1, 0.2, 0.3, 0.4, 0.5, 0.6],  # step 2: the final ranking
              3: [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]}


def test_pruner__never_before_the_warmup_even_far_below_the_median() -> None:
    pruner = PredictivePruner(warmup_step=3, min_rho=-1.0, n_startup=1)
    study = _study(FINALS, PREDICTIVE, pruner)
    frozen = _running(study, {1: 0.0, 2: 0.0})
    assert pruner.decision(study, frozen)[0] is False  # step 2 < warm-up 3
    frozen = _running(study, {1: 0.0, 2: 0.0, 3: 0.0})
    assert pruner.prune(study, frozen) is True  # step 3: allowed and below the median


def test_pruner__waits_for_a_step_whose_values_predict_the_final_ones() -> None:
    pruner = PredictivePruner(warmup_step=1, min_rho=0.7, n_startup=5)
    study = _study(FINALS, PREDICTIVE, pruner)
    prune, rho, n, median = pruner.decision(study, _running(study, {1: 0.0}))
    assert prune is False and rho < 0.7 and n == 6  # step 1 ranks nothing: no pruning
    prune, rho, n, median = pruner.decision(study, _running(study, {1: 0.0, 2: 0.0}))
    assert prune is True and rho == pytest.approx(1.0) and median == pytest.approx(0.35)
    assert pruner.decision(study, _running(study, {1: 0.0, 2: 0.36}))[0] is False  # above the median


def test_pruner__needs_enough_complete_trials() -> None:
    pruner = PredictivePruner(warmup_step=1, min_rho=0.0, n_startup=5)
    study = _study(FINALS[:4], {2: FINALS[:4]}, pruner)
    assert pruner.decision(study, _running(study, {2: 0.0}))[:3:2] == (False, 4)


def test_pruner__keeps_a_weak_replicate_of_a_configuration_that_did_well() -> None:
    pruner = PredictivePruner(warmup_step=1, min_rho=0.7, n_startup=5)
    study = _study(FINALS, PREDICTIVE, pruner)  # all complete trials have ref_size 2; median 0.35 at step 2
    study.add_trial(create_trial(state=TrialState.COMPLETE, value=0.9, params={"ref_size": 32},
                                 distributions=DIST, intermediate_values={2: 0.9}))
    study.enqueue_trial({"ref_size": 32})
    weak = _running(study, {2: 0.2})  # 0.2 < median 0.35, but (0.2 + 0.9) / 2 = 0.55 > 0.35
    assert weak.params == {"ref_size": 32}
    prune, rho, n, median = pruner.decision(study, weak)
    assert prune is False and median == pytest.approx(0.4)  # 7 complete: median of 0.1..0.6, 0.9
    study.enqueue_trial({"ref_size": 16})
    alone = _running(study, {2: 0.2})  # the same value without a good replicate: pruned
    assert pruner.decision(study, alone)[0] is True
