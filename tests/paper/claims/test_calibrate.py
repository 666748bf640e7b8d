"""Calibration of the claim tests by simulation (paper/claims/calibrate.py) and its CLI.
Fast tests run few simulations and only catch gross errors; the real calibration (the
committed paper/claims/calibration.json, `bench calibrate`) is checked for its verdict and
re-run in the slow test. Runtime: ~15 s fast, a few minutes slow."""
from __future__ import annotations

import json

import pandas as pd
import pytest

from bench.cli import main
from paper.claims.calibrate import FAMILIES, SCENARIOS, calibrate, ci_coverage, null_limit


@pytest.fixture(scope="module")
def quick():
    return calibrate(sims=24, seed=0, seed_counts=(3,))


def test_calibrate__every_scenario_at_every_seed_count_and_truth(quick):
    assert len(quick) == len(SCENARIOS) * 2
    assert set(quick["truth"]) == {"null", "effect"}
    assert set(quick["test"]) == {"hier_above_dec", "gap_widens", "convergence", "above_ic3net",
                                  "no_collisions", "few_corrections", "above_baselines"}


def test_calibrate__nothing_wildly_off_with_few_simulations(quick):
    null = quick[quick["truth"] == "null"]
    assert (null["rate"] <= 0.25).all(), null  # 24 sims: 5% true rate gives <= 6/24 w.p. > 0.999
    eff = quick[quick["truth"] == "effect"].set_index("scenario")["rate"]
    assert eff["mean correction rate 5%"] >= 0.5  # the checks decide at 0.0125 (paper.claims.verdicts)
    assert eff["no collisions"] == 1.0
    assert eff["+3 final reward"] >= 0.1


def test_calibrate__a_subset_of_scenarios_gives_the_same_rows(quick):
    sub = calibrate(sims=24, seed=0, seed_counts=(3,), scenarios=FAMILIES)
    assert len(sub) == 2 * len(FAMILIES) == 8
    whole = quick[quick["scenario"].isin(sub["scenario"])].reset_index(drop=True)
    pd.testing.assert_frame_equal(sub.reset_index(drop=True), whole)


def test_calibrate__is_seeded():
    a = calibrate(sims=6, seed=1, seed_counts=(3,))
    assert a.equals(calibrate(sims=6, seed=1, seed_counts=(3,)))


def test_null_limit__two_mc_standard_errors():
    assert null_limit(1000) == pytest.approx(0.05 + 2 * (0.05 * 0.95 / 1000) ** 0.5)


def test_ci_coverage__the_printed_intervals_at_the_runs_own_spread():
    cov = ci_coverage(sims=200, seed=0)
    rates = cov[cov["metric"] == "success_rate"]
    assert len(rates) and set(rates["seeds"]) <= {3, 5} | set(rates["seeds"])
    assert (rates["median"] >= 0.93).all()  # the logit t interval at the paper grid's groups
    assert (rates["lowest"] <= rates["median"]).all()


def test_cli_calibrate__json_and_out_file(capsys, tmp_path):
    out = tmp_path / "cal.json"
    with pytest.raises(SystemExit) as exc:
        main(["calibrate", "--sims", "10", "--coverage-sims", "10", "--json", "--out", str(out)])
    text = capsys.readouterr().out
    rep = json.loads(text)
    assert exc.value.code == (0 if rep["all_null_ok"] else 1)
    assert json.loads(out.read_text()) == rep
    assert {"meta", "calibration", "coverage", "all_null_ok"} <= set(rep)


@pytest.mark.slow
def test_calibrate__null_rates_within_five_percent_plus_mc_error():
    single = [i for i in range(len(SCENARIOS)) if i not in FAMILIES]
    cal = calibrate(sims=400, seed=7, scenarios=single)
    assert cal["null_ok"].all(), cal[~cal["null_ok"]]
    assert cal["contra_ok"].all(), cal[~cal["contra_ok"]]

