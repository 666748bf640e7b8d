"""Trial seeds, the objective's tie-break and a worker's segments (runtime ~1 s)."""
from __future__ import annotations

import math

import pytest

from envs.errors import BenchError
from studies.objective import (
    TrialSettings,
    TrialWorker,
    eval_seed,
    objective_values,
    squash_return,
)


def test_replicate_seed__derives_from_study_seed_and_replicate() -> None:
    from studies.schedule import replicate_seed

    seeds = {replicate_seed(0, n) for n in range(100)}
    assert len(seeds) == 100
    assert replicate_seed(0, 5) == replicate_seed(0, 5)
    assert replicate_seed(1, 5) != replicate_seed(0, 5)
    assert eval_seed(0) not in seeds


def test_objective__return_only_breaks_ties() -> None:
    n = 8
    # one more robot out of 8 x 20 episodes beats any return difference
    low_success_high_return = objective_values(0.5, 1e6, "success", n)[0]
    high_success_low_return = objective_values(0.5 + 1 / 160, -1e6, "success", n)[0]
    assert high_success_low_return > low_success_high_return
    assert objective_values(0.5, 10.0, "success", n)[0] > objective_values(0.5, 5.0, "success", n)[0]
    assert 0.0 < squash_return(-500.0, n) < squash_return(0.0, n) < squash_return(500.0, n) < 1.0


def test_objective__multi_objective_is_success_and_return() -> None:
    assert objective_values(0.25, -3.0, "success,return", 8) == [0.25, -3.0]


def test_worker__streams_one_segment_per_eval_every_and_ends_done(settings: TrialSettings) -> None:
    spec = settings.spec({"ref_size": 8, "search_radius": 2}, seed=3, eval_seed=eval_seed(0))
    worker = TrialWorker(spec)
    segs = [worker.step() for _ in range(settings.iterations)]
    assert [s.step for s in segs] == [1, 2, 3]
    assert [s.done for s in segs] == [False, False, True]
    assert [s.eval_episodes for s in segs] == [10, 10, 10]  # report_chunks=2 chunks of 5, then all
    assert segs[-1].episodes == 12
    assert all(0.0 <= s.success_rate <= 1.0 for s in segs)


def test_settings__a_bad_value_is_named() -> None:
    with pytest.raises(BenchError, match="loss_p"):
        TrialSettings.make(loss_p=1.5)
    with pytest.raises(BenchError, match="n_robots"):
        TrialSettings.make(method="fake_hier", n_robots=500).cell({"ref_size": 2}, seed=0)


def test_trial_cell__sampled_cell_fields_set_the_cell_and_other_names_the_method_params() -> None:
    settings = TrialSettings.make(method="decentralized", n_robots=4)
    cell = settings.cell({"lr": 1e-3, "search_radius": 1}, seed=5)
    assert cell.search_radius == 1 and cell.params["lr"] == 1e-3 and "search_radius" not in cell.params
    assert cell.method_params().lr == 1e-3


def test_filter_rates__mean_the_episodes_the_filter_ran_on_else_nan() -> None:
    from studies.objective import filter_rates

    rows = [{"fallback_rate": 0.2, "correction_rate": 0.1}, {"fallback_rate": float("nan"), "correction_rate": 0.0},
            {"fallback_rate": 0.4, "correction_rate": 0.3}, {"correction_rate": 0.0}]
    assert filter_rates(rows) == pytest.approx((0.3, 0.2))  # the episodes without a filter call are left out
    no_filter = filter_rates(rows[1:2] + rows[3:])  # a baseline: correction 0, fallback NaN -> both NaN
    assert math.isnan(no_filter[0]) and math.isnan(no_filter[1])
