"""Table I's bound, value and trend tests (paper/claims/verdicts_bounds.py) and their claims
(paper/claims/table1_claims.py). Runtime: a few seconds."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from paper.claims.table1_claims import (
    FALLBACK_BOUND,
    PAPER_SLOPE,
    PRINT_BOUND,
    claim_collisions_printed,
    claim_mean_candidates,
    claim_normal_search,
    claim_searches_grow,
)
from paper.claims.verdicts import CONTRADICTED, INCONCLUSIVE, NOT_ENOUGH, SUPPORTED, TEST_ALPHA
from paper.claims.verdicts_bounds import (
    NEAR_TOL,
    check_below,
    check_near,
    check_trend,
    trend_weights,
)
from reports.stats import t_test


def test_check_below__direction_numbers_and_its_contradiction_level():
    v, nums, test = check_below(np.array([0.01, 0.02, 0.03]), 0.07, "fallback rate")
    assert v == SUPPORTED
    # the logit-scale interval (inside [0, 1]; the t interval would be -0.484%, 4.48%); the test is the t
    assert nums.startswith("fallback rate 2% [95% CI 0.453%, 7.03%] vs 7%; one-sided p = 0.00654")
    near_one = check_below(np.array([0.6, 0.9, 1.0]), 0.995, "r")[1]
    assert "r 83.3% [95% CI 2.9%, 100%; uninformative] vs 99.5%" in near_one  # t: 31.6%, 135%
    not_a_rate = check_below(np.array([0.01, 0.02, 0.03]), 0.07, "x", pct=False)[1]
    assert "[95% CI 0.00458, 0.0981] vs 0.07" in not_a_rate  # pct=False: a count's Cox interval, >= 0
    assert test == "one-sample t over 3 seeds against 7%"
    assert check_below(np.array([0.07, 0.08, 0.09]), 0.03, "x")[0] == CONTRADICTED
    assert check_below(np.array([0.0, 0.05, 0.1]), 0.05, "x")[0] == INCONCLUSIVE
    base = np.array([0.0, 1.0, 2.0])
    for s in np.linspace(0.0, 40.0, 40001):  # above 1 with one-sided p in (TEST_ALPHA / 3, TEST_ALPHA)
        p = t_test([base + s], [1.0], null=1.0).p_greater
        if TEST_ALPHA / 3 < p < TEST_ALPHA:
            break
    m = base + s
    assert TEST_ALPHA / 3 < p < TEST_ALPHA
    assert check_below(m, 1.0, "x", pct=False)[0] == CONTRADICTED
    v, nums, test = check_below(m, 1.0, "x", contra_alpha=TEST_ALPHA / 3, pct=False)
    assert v == INCONCLUSIVE and "0.0042 (Bonferroni)" in test and nums.startswith("x ")
    assert check_below(np.array([0.01, np.nan, 0.02]), 0.05, "x") == (NOT_ENOUGH, "2 seeds (need >= 3 per side)", "-")


def test_check_near__inside_outside_and_between_the_band():
    assert check_near(np.array([3.7, 3.8, 3.9]), 3.79, "c")[0] == SUPPORTED
    assert check_near(np.array([180.0, 200.0, 220.0]), 3.79, "c")[0] == CONTRADICTED  # above
    assert check_near(np.array([0.5, 0.6, 0.7]), 3.79, "c")[0] == CONTRADICTED  # below
    assert check_near(np.array([1.0, 4.0, 9.0]), 3.79, "c")[0] == INCONCLUSIVE
    v, nums, test = check_near(np.array([3.7, 3.8, 3.9]), 4.0, "mean candidates")
    assert nums.startswith("mean candidates 3.8 [95% CI 3.56, 4.06] vs paper 4 (band 2..6); p(above the band) = ")
    assert test == "equivalence, two one-sided t over 3 seeds, +-50% of the paper's value"
    assert NEAR_TOL == 0.5
    assert check_near(np.array([1.0, 2.0]), 4.0, "x")[0] == NOT_ENOUGH


def test_check_near__each_side_contradicts_at_half_the_level():
    # above the upper edge 6 with one-sided p between T / 2 and T: not a contradiction
    for s in np.linspace(0.0, 40.0, 40001):
        m = np.array([0.0, 1.0, 2.0]) + 6.0 + s
        p = t_test([m], [1.0], null=6.0).p_greater
        if TEST_ALPHA / 2 < p < TEST_ALPHA:
            break
    assert TEST_ALPHA / 2 < p < TEST_ALPHA
    assert check_near(m, 4.0, "x")[0] == INCONCLUSIVE
    lo = 2.0 - (m - 6.0)  # mirrored below the lower edge 2: the same p
    assert check_near(lo, 4.0, "x")[0] == INCONCLUSIVE
    for s in np.linspace(0.0, 40.0, 40001):  # p in (T / 3, T / 2): contradicted at / 2, not at / 3
        m2 = np.array([0.0, 1.0, 2.0]) + 6.0 + s
        p2 = t_test([m2], [1.0], null=6.0).p_greater
        if TEST_ALPHA / 3 < p2 < TEST_ALPHA / 2:
            break
    assert check_near(m2, 4.0, "x")[0] == CONTRADICTED
    assert check_near(2.0 - (m2 - 6.0), 4.0, "x")[0] == CONTRADICTED
    assert check_near(m2, 4.0, "x", contra_alpha=TEST_ALPHA / 3)[0] == INCONCLUSIVE


def test_trend_weights__the_ols_slope_of_group_means():
    w = trend_weights([40, 60, 80])
    assert w.tolist() == pytest.approx([-1 / 40, 0.0, 1 / 40])
    assert float(np.dot(trend_weights([40, 60, 80, 90, 100]), [3.79, 16.44, 24.15, 35.63, 24.68])) == \
        pytest.approx(PAPER_SLOPE)
    assert PAPER_SLOPE == pytest.approx(np.polyfit([40, 60, 80, 90, 100], [3.79, 16.44, 24.15, 35.63, 24.68], 1)[0])


def test_check_trend__rising_falling_flat_and_too_few():
    up = [np.array([1.0, 2.0, 3.0]) + n / 10 for n in (40, 60, 80)]
    v, nums, test = check_trend(up, [40, 60, 80], "mean candidates")
    assert v == SUPPORTED and "(40: 6, 60: 8, 80: 10); slope 0.1 per robot" in nums
    assert test == "Welch t on the OLS slope of 3 per-seed means on N"
    assert check_trend(up[::-1], [40, 60, 80], "c")[0] == CONTRADICTED
    assert check_trend([up[0]] * 3, [40, 60, 80], "c")[0] == INCONCLUSIVE
    assert check_trend([up[0], up[1][:2]], [40, 60], "c") == (NOT_ENOUGH, "3 vs 2 seeds (need >= 3 per side)", "-")
    v, _, test = check_trend(up[::-1], [40, 60, 80], "c", contra_alpha=1e-12)
    assert v == INCONCLUSIVE and "Bonferroni" in test


def _evals(n: int, col: str, values: list[float], mode: str = "argmax", method: str = "hierarchical",
           filt: bool = True) -> pd.DataFrame:
    return pd.DataFrame({"cell_id": [f"{method}{n}-{k}" for k in range(len(values))], "episode": 0,
                         col: values, "method": method, "n_robots": n, "loss_p": 0.2,
                         "safety_filter": filt, "execution": mode})


def test_claims_table1__each_reads_its_column_per_mode_with_power():
    ev = pd.concat([_evals(40, "collision_rate", [0.0, 0.0, 0.0]),
                    _evals(40, "collision_rate", [0.010, 0.011, 0.012], "sample")])
    c = claim_collisions_printed(ev, configs=[(40, 0.2)])
    assert [(k.execution, k.verdict) for k in c.checks] == [("argmax", SUPPORTED), ("sample", CONTRADICTED)]
    assert c.checks[0].power == 1.0 and "a true rate of 0" in c.checks[0].power_text
    assert "against 0.005%" in c.checks[0].test and PRINT_BOUND == 0.00005
    fb = claim_normal_search(_evals(60, "fallback_rate", [0.4, 0.5, 0.6]), configs=[(60, 0.2)])
    assert fb.verdict == CONTRADICTED and "fallback rate 50%" in fb.checks[0].numbers
    assert "a true rate of 2.5%" in fb.checks[0].power_text and FALLBACK_BOUND == 0.05
    cand = claim_mean_candidates(_evals(40, "mean_candidates", [180.0, 200.0, 220.0]), configs=[(40, 0.2), (50, 0.2)])
    assert [(k.config, k.verdict) for k in cand.checks] == [("N = 40, p = 0.2", CONTRADICTED),
                                                            ("N = 50, p = 0.2", NOT_ENOUGH)]
    assert "paper 3.79" in cand.checks[0].numbers and "the paper's 3.79" in cand.checks[0].power_text
    off = claim_mean_candidates(_evals(40, "mean_candidates", [3.8] * 3, filt=False), configs=[(40, 0.2)])
    assert off.verdict == NOT_ENOUGH


def test_claim_searches_grow__one_check_per_mode_over_the_team_sizes():
    ns = (40, 60, 80, 90, 100)
    ev = pd.concat([_evals(n, "mean_candidates", [n / 4 + d for d in (0.0, 1.0, 2.0)], mode)
                    for n in ns for mode in ("argmax", "sample")]
                   + [_evals(40, "mean_candidates", [1.0, 2.0, 3.0], "sample@0.5")])  # one N only
    c = claim_searches_grow(ev)
    assert [(k.config, k.execution, k.verdict) for k in c.checks] == [
        ("N = 40..100, p = 0.2", "argmax", SUPPORTED), ("N = 40..100, p = 0.2", "sample", SUPPORTED)]
    assert "slope 0.25 per robot" in c.checks[0].numbers and "0.43 per robot" in c.checks[0].power_text
    down = pd.concat([_evals(n, "mean_candidates", [100 - n / 4 + d for d in (0.0, 1.0, 2.0)]) for n in ns])
    assert claim_searches_grow(down).verdict == CONTRADICTED
    assert claim_searches_grow(down[down["n_robots"] != 90]).checks[0].verdict == NOT_ENOUGH
    assert claim_searches_grow(down, configs=[(40, 0.2), (60, 0.2)]).checks[0].config == "N = 40..60, p = 0.2"
