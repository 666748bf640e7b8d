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


def test_point_table__a_pruned_replicate_disqualifies_and_every_state_is_counted() -> None:
    """A configuration with enough complete replicates but one pruned is not eligible (its
    mean would be biased upwards by the survivors): the best is the next one. Running,
    waiting and failed trials are counted, never averaged."""
    trials = _trials([
        (32, 1, "COMPLETE", 0.90), (32, 1, "COMPLETE", 0.92), (32, 1, "PRUNED", 0.20),  # 2 complete + 1 pruned
        (8, 2, "COMPLETE", 0.60), (8, 2, "COMPLETE", 0.62), (8, 2, "RUNNING", math.nan),
        (8, 2, "WAITING", math.nan), (8, 2, "FAIL", math.nan),
    ])
    trials["team_return"] = [1.0, 3.0, -50.0, 5.0, 7.0, math.nan, math.nan, math.nan]
    best = best_point(trials, replicates=2)
    assert (best["ref_size"], best["search_radius"]) == (8, 2)
    table = point_table(trials, 2).set_index("ref_size")
    assert table.loc[32, ["complete", "pruned", "running", "failed"]].tolist() == [2, 1, 0, 0]
    assert table.loc[8, ["complete", "pruned", "running", "failed"]].tolist() == [2, 0, 2, 1]
    assert not table.loc[32, "eligible"] and table.loc[8, "eligible"]
    assert table.loc[32, "success_rate"] == pytest.approx(0.91)  # complete replicates only
    assert table.loc[32, "team_return"] == pytest.approx(2.0)
    assert table.loc[8, "trials"] == "3,4,5,6,7"
    # a frame from before a column existed still gives the table, with NaN there
    old = point_table(trials.drop(columns=["value_return", "team_return", "success_rate"]), 2)
    assert old[["team_return", "value_return", "success_rate"]].isna().all().all()
    assert old.columns.tolist() == point_table(trials, 2).columns.tolist()  # the same columns, no index column
    # no trial yet: an empty table that still has its columns
    empty = point_table(trials.iloc[:0], 2)
    assert empty.empty and empty.columns.tolist()[:3] == ["complete", "pruned", "running"]


def test_point_table__ties_go_to_the_higher_return_then_to_the_configuration_order() -> None:
    """Equal mean objectives: the higher mean return first (the second objective where there is
    one, else the team return); configurations with no value keep their parameter order."""
    trials = _trials([
        (16, 1, "PRUNED", 0.1), (4, 1, "PRUNED", 0.1),  # listed out of order; no complete trial
        (8, 2, "COMPLETE", 0.5), (8, 2, "COMPLETE", 0.5),
        (2, 2, "COMPLETE", 0.5), (2, 2, "COMPLETE", 0.5),
    ])
    trials["team_return"] = [0.0, 0.0, 9.0, 9.0, 1.0, 1.0]
    table = point_table(trials, 2)
    assert table["ref_size"].tolist() == [8, 2, 4, 16]
    assert "index" not in table.columns
    trials["value_return"] = [math.nan, math.nan, 3.0, 3.0, 5.0, 5.0]  # the second objective decides
    assert point_table(trials, 2)["ref_size"].tolist() == [2, 8, 4, 16]
    # trials without any searched parameter give an empty table, not an error
    assert point_table(trials.drop(columns=["ref_size", "search_radius"]), 2).empty
