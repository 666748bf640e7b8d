"""Power beside every verdict (paper/claims/power.py, paper/claims/claim_power.py, Check.verdict_words).
Runtime: a few seconds."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats as sps

from paper.claims.claim_power import (
    power_below,
    power_convergence,
    power_curves,
    power_gap,
    power_greater,
    power_near,
    power_trend,
)
from paper.claims.claims import Check
from paper.claims.power import (
    COULD_NOT,
    MAX_SEEDS,
    NO_POWER,
    Power,
    contrast_power,
    power_of,
    seeds_for,
    weakest,
)
from paper.claims.sides import Side
from paper.claims.verdicts import INCONCLUSIVE, MIN_SEEDS, SUPPORTED, TEST_ALPHA
from reports.stats import t_test


def test_contrast_power__one_sample_is_the_noncentral_t_by_hand():
    # sd 1, n 4, effect 1: se 1/2, ncp 2, df 3
    want = sps.nct.sf(sps.t.isf(0.05, 3), 3, 2.0)
    assert float(contrast_power([1.0], [4], [1.0], 1.0, alpha=0.05)) == pytest.approx(want, rel=1e-12)
    assert float(contrast_power([1.0], [4], [1.0], 1.0, alpha=0.01)) < want  # a stricter level
    assert float(contrast_power([1.0], [4], [-1.0], 1.0, alpha=0.05)) == pytest.approx(want, rel=1e-12)
    at_checks = sps.nct.sf(sps.t.isf(TEST_ALPHA, 3), 3, 2.0)  # the default: the checks' level
    assert float(contrast_power([1.0], [4], [1.0], 1.0)) == pytest.approx(at_checks, rel=1e-12)


def test_contrast_power__matches_the_rejection_rate_of_the_t_test_it_describes():
    rng = np.random.default_rng(3)
    x = rng.normal(0.8, 1.0, (3000, 5))
    rate = np.mean([t_test([r], [1.0]).p_greater < 0.05 for r in x])
    assert float(contrast_power([1.0], [5], [1.0], 0.8, alpha=0.05)) == pytest.approx(rate, abs=0.03)


def test_contrast_power__welch_df_from_each_groups_spread_and_count():
    # sds 1 and 2 over 5 and 3 seeds: c = 1/5, 4/3; df = (c1+c2)^2 / (c1^2/4 + c2^2/2)
    c1, c2 = 1 / 5, 4 / 3
    df = (c1 + c2) ** 2 / (c1 * c1 / 4 + c2 * c2 / 2)
    want = sps.nct.sf(sps.t.isf(0.05, df), df, 1.5 / np.sqrt(c1 + c2))
    assert float(contrast_power([1.0, 2.0], [5, 3], [1.0, -1.0], 1.5, alpha=0.05)) == pytest.approx(want, rel=1e-12)


def test_contrast_power__no_variance_is_decided_exactly():
    assert float(contrast_power([0.0], [3], [1.0], 0.1)) == 1.0
    assert float(contrast_power([0.0], [3], [1.0], -0.1)) == 0.0


def test_seeds_for__the_smallest_count_that_reaches_eighty_percent():
    n = seeds_for([1.0, 1.0], [1.0, -1.0], 1.0)
    at = lambda k: float(contrast_power([1.0, 1.0], [k, k], [1.0, -1.0], 1.0))  # noqa: E731
    assert at(n) >= 0.8 > at(n - 1)
    assert seeds_for([0.0], [1.0], 0.1) == MIN_SEEDS  # fewer seeds are never decided
    assert seeds_for([1.0], [1.0], 1e-4) is None  # more than MAX_SEEDS


def test_power_of__own_counts_and_spreads_and_nan_without_two_seeds():
    a, b = np.array([1.0, 2.0, 3.0, 4.0, np.nan]), np.array([0.0, 2.0, 4.0])
    p = power_of([a, b], [1.0, -1.0], 1.0, "w")
    assert p.power == pytest.approx(float(contrast_power([a[:4].std(ddof=1), 2.0], [4, 3], [1.0, -1.0], 1.0)))
    assert p.seeds_80 == seeds_for([a[:4].std(ddof=1), 2.0], [1.0, -1.0], 1.0) and p.effect == "w"
    assert power_of([np.array([1.0]), b], [1.0, -1.0], 1.0, "w") is NO_POWER


def test_weakest__the_smallest_power_and_the_largest_seed_need():
    w = weakest("both", Power(0.9, 4, "a"), Power(0.3, 12, "b"))
    assert (w.power, w.seeds_80, w.effect, w.bound) == (0.3, 12, "both", True)
    assert weakest("x", Power(0.9, 4, "a"), Power(0.3, None, "b")).seeds_80 is None
    assert weakest("x", Power(0.9, 4, "a"), NO_POWER) is NO_POWER


def test_power_text__effect_seed_need_and_bound():
    assert Power(0.234, 15, "+1 x").text() == "power 23% to detect +1 x; 80% power needs 15 seeds per side"
    assert Power(0.5, None, "e", bound=True).text() == (
        f"power <= 50% to detect e; 80% power needs > {MAX_SEEDS} seeds per side")
    assert NO_POWER.text() == "-"


def test_verdict_words__could_not_decide_only_where_the_interval_spans_both_sides():
    both = Side(-0.2, -1.0, 1.0, 0.0, np.inf)  # points against, interval across 0
    assert Check("c", INCONCLUSIVE, "", "", power=0.49, side=both).verdict_words == \
        f"{COULD_NOT} (points against the claim)"
    assert Check("c", INCONCLUSIVE, "", "", power=0.5, side=both).verdict_words == \
        "undecided: points against the claim; its 95% CI spans both the claim and its negation"
    # the audit's case: 74.8% [35.2, 100] against "< 8%": low power, yet the interval excludes the claim
    wrong_side = Side(0.748, 0.352, 1.0, -np.inf, 0.08)
    words = Check("c", INCONCLUSIVE, "", "", power=0.03, side=wrong_side).verdict_words
    assert COULD_NOT not in words and words == "undecided: points against the claim; its 95% CI excludes the claim"
    right_side = Side(0.03, 0.01, 0.05, -np.inf, 0.08)
    assert Check("c", INCONCLUSIVE, "", "", power=0.1, side=right_side).verdict_words.endswith(
        "points toward the claim; its 95% CI excludes the claim's negation")
    assert Check("c", SUPPORTED, "", "", power=0.1, side=both).verdict_words == SUPPORTED
    assert Check("c", INCONCLUSIVE, "", "").verdict_words == INCONCLUSIVE  # no estimate: nothing said


def test_sides__convergence_points_against_when_the_drift_is_beyond_tolerance():
    from paper.claims.sides import side_convergence

    t = np.arange(100.0)
    flat = [np.minimum(t, 50.0) + k for k in range(3)]
    rising = [t * (1.0 + 0.1 * k) for k in range(3)]
    assert side_convergence(flat).points == "toward the claim"
    assert side_convergence(rising).points == "against the claim"  # gain > 0 but still rising
    assert not side_convergence(flat[:2]).known


def test_pooled_sign_test__exact_binomial_both_ways():
    from paper.claims.pooled import MIN_DECIDABLE, sign_test

    r = sign_test(["against the claim"] * 16 + ["toward the claim"] * 2)
    assert r.verdict == "contradicted" and r.p_against == pytest.approx(sps.binom.cdf(2, 18, 0.5))
    assert "16 of 18 checks point against the claim" in r.text()
    assert sign_test(["toward the claim"] * 7).verdict == SUPPORTED  # 0.5^7 = 0.0078 < 0.0125
    assert sign_test(["toward the claim"] * 6).verdict == INCONCLUSIVE  # 0.5^6 = 0.0156
    assert MIN_DECIDABLE == 7
    assert sign_test(["", "toward the claim"]).toward == 1 and sign_test([""]).verdict == "not enough seeds"


def test_claim_power__stated_effects_of_each_check():
    a, b = np.array([10.0, 12.0, 14.0]), np.array([20.0, 20.0, 23.0])
    g = power_greater(a, b)
    assert g.effect == "+2.1 final reward (10% of the baseline's)"
    assert g.power == pytest.approx(power_of([a, b], [1.0, -1.0], 2.1, "").power)
    gap = power_gap([a, b, a, b])
    assert gap.power == pytest.approx(power_of([a, b, a, b], [1.0, -1.0, -1.0, 1.0], 2.1, "").power)
    m = np.array([0.01, 0.02, 0.03])
    assert power_below(m, 0.08, 0.03, "w").power == pytest.approx(power_of([m], [1.0], 0.05, "").power)
    near = power_near(np.array([3.0, 4.0, 5.0]), 4.0)
    assert near.bound and near.power == pytest.approx(power_of([np.array([3.0, 4.0, 5.0])], [1.0], 2.0, "").power)
    t = power_trend([a, b, a], [40, 60, 80], 0.5)
    assert t.power == pytest.approx(power_of([a, b, a], [-1 / 40, 0.0, 1 / 40], 0.5, "").power)


def test_power_curves__the_mean_test_and_each_percentile_band_at_its_level():
    h = [np.linspace(0.2, 0.8, 20) + d for d in (0.0, 0.05, 0.1)]
    i = [np.linspace(0.2, 0.8, 20) + d for d in (0.0, 0.1, 0.2)]
    p = power_curves(h, i)
    mean_only = power_of([np.array([x.mean() for x in h]), np.array([x.mean() for x in i])],
                         [1.0, -1.0], 0.1, "")
    assert p.bound and p.power <= mean_only.power
    # the band at level 0.05 / 5 with margin 0.15 is the weaker part here
    band = power_of([np.array([0.2, 0.25, 0.3]) + 0.03, np.array([0.2, 0.3, 0.4]) + 0.03], [1.0, -1.0],
                    0.15, "", alpha=TEST_ALPHA / 5)
    assert p.power == pytest.approx(min(mean_only.power, band.power), rel=0.2)


def test_power_convergence__own_gain_no_drift():
    curves = [np.concatenate([np.zeros(40), np.full(10, g)]) + 0.01 * np.arange(50) % 0.03
              for g in (4.0, 5.0, 6.0)]
    p = power_convergence(curves, 0.2, 0.2)
    assert p.bound and p.effect.startswith("its own mean gain")
    assert 0.0 <= p.power <= 1.0
