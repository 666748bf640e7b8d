"""The calibration on the committed reproduction's own spread (paper/claims/calibrate_data.py):
its vectorized tests agree verdict for verdict with the claim kernels, a small-sim smoke
of the machinery, and the committed paper/claims/calibration.json. Runtime: ~20 s."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from paper.claims import calibrate_data as D
from paper.claims.verdicts import (
    BAND_PCT,
    CONTRADICTED,
    INCONCLUSIVE,
    SUPPORTED,
    check_convergence,
    check_corrections,
    check_curves,
    check_gap,
    check_greater,
)
from paper.claims.verdicts_bounds import check_below, check_near, check_trend
from paper.sections import CALIBRATION
from reports.stats import curve_shape, quantile_curve

CODE = {SUPPORTED: 1, INCONCLUSIVE: 0, CONTRADICTED: -1}
M = 60  # draws per comparison


def _agree(vec: np.ndarray, kernel: list[str]) -> None:
    got = [CODE[v] for v in kernel]
    assert vec.tolist() == got
    assert len(set(got)) >= 2  # the draws reach more than one verdict


@pytest.mark.parametrize("contra", [0.0125, 0.0125 / 15])
def test_vectorized_mean_tests__agree_with_the_kernels(contra):
    rng = np.random.default_rng(1)
    a, b = rng.normal(0.9, 1.0, (M, 5)), rng.normal(0.0, 2.0, (M, 3))
    _agree(D.v_greater([a, b], contra), [check_greater(x, y, "", contra)[0] for x, y in zip(a, b, strict=True)])
    g = [rng.normal(m, 1.0, (M, 3)) for m in (1.5, 0.0, 0.0, 0.0)]
    _agree(D.v_gap(g, contra), [check_gap([x[j] for x in g], 60, 20, contra)[0] for j in range(M)])
    m = rng.normal(0.08, 0.03, (M, 3))
    _agree(D.make_below(0.08)([m], contra), [check_corrections(x, contra_alpha=contra)[0] for x in m])
    _agree(D.make_below(0.08)([m], contra), [check_below(x, 0.08, "", contra)[0] for x in m])
    c = rng.normal(4.0, 1.5, (M, 3)) * rng.choice([1.0, 3.0], (M, 1))
    _agree(D.make_near(4.0)([c], contra), [check_near(x, 4.0, "", contra)[0] for x in c])
    t = [rng.normal(n / 20, 1.0, (M, 3)) for n in (40, 60, 80)]
    _agree(D.make_trend([40, 60, 80])(t, contra),
           [check_trend([x[j] for x in t], [40, 60, 80], "", contra)[0] for j in range(M)])


def test_vectorized_curve_test__agrees_with_check_curves():
    rng = np.random.default_rng(2)
    shift = rng.uniform(-0.5, 0.5, (M, 1, 1))  # per draw: hierarchical far below .. far above
    eps = [np.clip(rng.beta(4, 2, (M, s, 40)) + d + rng.normal(0, 0.03, (M, s, 1)), 0, 1)
           for s, d in ((5, shift), (3, 0.0))]
    vec = [np.concatenate([e.mean(axis=2, keepdims=True),
                           np.stack([[quantile_curve(x, BAND_PCT) for x in sim] for sim in e])], axis=2)
           for e in eps]
    for contra in (0.0125, 0.0125 / 18):
        _agree(D.v_curves(vec, contra), [check_curves(list(eps[0][j]), list(eps[1][j]), contra)[0]
                                          for j in range(M)])


def test_vectorized_convergence_test__agrees_with_check_convergence():
    rng = np.random.default_rng(4)
    e = np.arange(100.0)
    gains = rng.uniform(-6.0, 6.0, (M, 1)) + rng.normal(0.0, 0.5, (M, 3))
    drift = rng.normal(0.0, 0.3, (M, 3))
    curves = [[g * np.minimum(e / 50, 1.0) + d * np.clip((e - 80) / 20, 0, 1) + rng.normal(0, 0.3, 100)
               for g, d in zip(gs, ds, strict=True)] for gs, ds in zip(gains, drift, strict=True)]
    gd = np.array([[[curve_shape(c, 0.2).gain, curve_shape(c, 0.2).drift] for c in sim] for sim in curves])
    for contra in (0.0125, 0.0125 / 3):
        _agree(D.v_convergence([gd], contra), [check_convergence(sim, contra_alpha=contra)[0] for sim in curves])


def test_combine_codes__as_verdicts_combine():
    v = np.array([[1, 1, 0, -1], [1, 0, 0, 1]])
    assert D.combine_codes(v).tolist() == [1, 0, 0, -1]


def _spec(null: float, effect: float) -> D.Spec:
    return D.Spec("c", "x", (3,), np.array([1.0]), np.array([null]), np.array([effect]), D.make_below(0.0),
                  z=np.array([-1.2, 0.6, 0.6, -0.3, 0.3]))


def test_spec_draw__means_spreads_and_sources():
    sp = _spec(0.0, -2.0)
    for source in D.SOURCES:
        x = sp.draw(np.random.default_rng(0), 20000, "null", source)[0]
        assert x.shape == (20000, 3)
        assert abs(x.mean()) < 0.03
    eff = sp.draw(np.random.default_rng(0), 20000, "effect", "resampled")[0]
    assert eff.mean() == pytest.approx(-2.0, abs=0.03)
    norm = sp.draw(np.random.default_rng(0), 20000, "null", "normal")[0]
    assert norm.std() == pytest.approx(1.0, abs=0.02)


def test_pooled__standardized_residuals_with_unit_variance():
    z = D._pooled([("a", [np.array([1.0, 2.0, 6.0])]), ("b", [np.array([5.0, 5.0, 5.0])])])
    assert z.shape == (6,) and z.std() == pytest.approx(1.0) and z[3:].tolist() == [0.0, 0.0, 0.0]
    assert z[2] > 0 > z[0]  # the collapse pattern kept: one seed far above two


def test_calibrate_specs__rows_per_check_and_whole_claim_with_their_se():
    specs = {"c": [_spec(0.0, -5.0), _spec(0.0, -5.0)]}
    cal = D.calibrate_specs(specs, sims=400, seed=0, sources=("normal",))
    assert len(cal) == 2 * 2 + 3
    assert set(cal["k"]) == {2} and cal["check"].str.startswith("whole claim (2 checks)").sum() == 3
    null = cal[(cal["truth"] == "null") & (cal["check"] == "x")]
    assert (null["rate"] <= 0.06).all()  # true level 0.0125
    eff = cal[cal["truth"] == "effect"]
    assert (eff["rate"] >= 0.7).all()  # mean 5 s.d. below the bound over 3 seeds
    r = cal.iloc[0]
    assert r["mc_se"] == pytest.approx(np.sqrt(r["rate"] * (1 - r["rate"]) / 400))
    assert cal.equals(D.calibrate_specs(specs, sims=400, seed=0, sources=("normal",)))  # seeded


def test_row__limits_for_support_and_contradiction():
    lim = D.null_limit(5000)
    assert lim == pytest.approx(0.05 + 2 * np.sqrt(0.05 * 0.95 / 5000))
    over = np.array([1] * 300 + [0] * 4700)
    assert not D._row("c", "x", "3", "s", "null", 1, 5000, over)["null_ok"]
    assert D._row("c", "x", "3", "s", "effect", 1, 5000, over)["null_ok"]  # power, no limit
    contra = -over
    assert not D._row("c", "x", "3", "s", "effect", 1, 5000, contra)["contra_ok"]
    assert D._row("c", "x", "3", "s", "null", 1, 5000, contra, boundary=False)["contra_ok"]


def test_collision_rows__the_exact_bound_gives_five_percent():
    rows = D.collision_rows(seed=0, sims=20000)
    null = rows[rows["truth"] == "null"].iloc[0]
    assert null["rate"] == pytest.approx(0.05, abs=0.006) and null["null_ok"]


@pytest.fixture(scope="module")
def committed() -> dict:
    return json.loads(CALIBRATION.read_text())


def test_committed_calibration__every_claim_checked_within_the_limit(committed):
    rep = committed
    cal = pd.DataFrame(rep["calibration"])
    assert rep["all_null_ok"] and rep["meta"]["sims"] >= 5000 and rep["meta"]["run"] == "reproduction/paper"
    assert set(cal["test"]) == {"hier_above_dec", "gap_widens", "convergence", "above_ic3net", "no_collisions",
                                "collisions_printed", "few_corrections", "table1_candidates", "searches_grow",
                                "normal_search", "above_baselines"}
    null = cal[cal["truth"] == "null"]
    assert (null["mc_se"] <= 0.005).all() and (null["contra_se"] <= 0.005).all()
    assert (null["rate"] <= D.null_limit(5000)).all()
    assert cal["contra_ok"].all() and cal["null_ok"].all()
    whole = cal[cal["check"].str.startswith("whole claim")]
    assert set(whole["test"]) >= {"hier_above_dec", "gap_widens", "convergence", "above_ic3net",
                                  "few_corrections", "collisions_printed", "table1_candidates", "normal_search",
                                  "above_baselines"}
    assert "5 vs 3" in set(cal["seeds"])  # the unequal seed counts of Fig. 2 at N = 40, p = 0.2
    assert set(cal["source"]) == {"resampled", "normal", "binomial"}


def test_committed_calibration__pooled_sign_tests_within_the_limit(committed):
    cal = pd.DataFrame(committed["calibration"])
    pooled = cal[cal["check"].str.startswith("pooled sign test")]
    assert set(pooled["test"]) >= {"above_ic3net", "few_corrections", "normal_search", "collisions_printed"}
    assert "table1_candidates" not in set(pooled["test"])  # a two-sided band: no sign test
    null = pooled[pooled["truth"] == "null"]
    assert (null["rate"] <= D.null_limit(5000)).all() and (null["contradicted"] <= D.null_limit(5000)).all()


def test_sign_codes__agree_with_the_pooled_sign_test():
    from paper.claims.pooled import sign_test

    rng = np.random.default_rng(0)
    pts = rng.random((18, 400)) < rng.random(400)  # (k checks, sims): toward or against
    codes = D.sign_codes(pts)
    words = {1: "supported", 0: "undecided", -1: "contradicted"}
    for j in range(pts.shape[1]):
        r = sign_test(["toward the claim" if p else "against the claim" for p in pts[:, j]])
        assert words[int(codes[j])] == r.verdict
