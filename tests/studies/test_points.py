"""Per-configuration means, CIs and the best configuration, on hand-made trials (~1 s)."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from envs.errors import BenchError
from studies.points import best_point, point_table, t_interval


def _trials(rows: list[tuple[int, int, str, float]]) -> pd.DataFrame:
    """(ref_size, search_radius, state, value) rows."""
    return pd.DataFrame({
        "number": range(len(rows)), "ref_size": [r[0] for r in rows], "search_radius": [r[1] for r in rows],
        "state": [r[2] for r in rows], "value": [r[3] for r in rows], "success_rate": [r[3] for r in rows],
        "team_return": [0.0] * len(rows), "value_return": [math.nan] * len(rows)})


def test_t_interval__by_hand() -> None:
    """The objective is a success rate: the t interval on the logit scale, inside [0, 1] (the plain
    t interval of these two replicates would be -0.83 .. 1.24)."""
    mean, lo, hi = t_interval(np.array([0.125, 0.288]))
    z = np.log(np.array([0.125, 0.288]) / np.array([0.875, 0.712]))
    half = 12.706204736 * np.std(z, ddof=1) / math.sqrt(2)  # t_{0.975, 1}
    assert mean == pytest.approx(0.2065)
    assert lo == pytest.approx(1 / (1 + np.exp(-(z.mean() - half))))
    assert hi == pytest.approx(1 / (1 + np.exp(-(z.mean() + half))))
    assert 0.0 < lo < 0.125 and 0.288 < hi < 1.0
    assert math.isnan(t_interval(np.array([0.4]))[1])


def test_best__is_the_highest_mean_not_the_single_highest_trial() -> None:
    trials = _trials([
        (4, 1, "COMPLETE", 0.95), (4, 1, "COMPLETE", 0.05),  # one lucky seed: mean 0.50
        (8, 2, "COMPLETE", 0.60), (8, 2, "COMPLETE", 0.62),  # consistent: mean 0.61
        (2, 0, "COMPLETE", 0.99), (2, 0, "PRUNED", 0.10),    # a pruned replicate: not eligible
        (16, 3, "COMPLETE", 0.97),                           # one replicate only
    ])
    best = best_point(trials, replicates=2)
    assert (best["ref_size"], best["search_radius"]) == (8, 2)
    assert best["value"] == pytest.approx(0.61) and best["complete"] == 2
    table = point_table(trials, 2)
    assert list(table["eligible"]) == [True, True, False, False]
    assert table.loc[table["ref_size"] == 2, "value"].item() == pytest.approx(0.99)  # complete ones only


def test_best__waits_for_every_point_of_an_exhaustive_search() -> None:
    trials = _trials([(4, 1, "COMPLETE", 0.5), (4, 1, "COMPLETE", 0.6), (8, 2, "COMPLETE", 0.7)])
    with pytest.raises(BenchError, match="1 of 2 configurations have 2 finished replicates"):
        best_point(trials, 2, n_points=2)
    more = _trials([(4, 1, "COMPLETE", 0.5), (4, 1, "COMPLETE", 0.6), (8, 2, "COMPLETE", 0.7),
                    (8, 2, "PRUNED", 0.1)])
    best = best_point(more, 2, n_points=2)  # (8, 2) is covered but not eligible (pruned replicate)
    assert (best["ref_size"], best["search_radius"]) == (4, 1)
    with pytest.raises(BenchError, match="none of the 1 configuration"):
        best_point(_trials([(4, 1, "COMPLETE", 0.5)]), 2)


def test_progress__eta_from_this_runs_throughput() -> None:
    from studies.progress import TuneSnapshot

    snap = TuneSnapshot(requested=40, finished=15, finished_now=5, running=2, elapsed_s=100.0)
    assert snap.eta_s == pytest.approx(100.0 / 5 * 25)  # 20 s per trial, 25 to go
    assert snap.line() == "[15/40 finished, 2 running, elapsed 1m40s, ETA 8m20s]"
    assert TuneSnapshot(40, 10, 0, 2, 5.0).eta_s is None
