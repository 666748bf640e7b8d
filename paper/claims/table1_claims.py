"""Table I's statements beyond "no collisions" and "fewer than 8%" (Sec. IV):
the collision rate at the paper's print precision, the mean candidates it prints, "the
mean number of searches generally increases for larger teams" and "an admissible control
can be identified within the normal safety search" (the fallback rate).

Claim builders over the store's evaluation table, like ``paper.claims.claims`` (whose
``_each`` gives each check its Bonferroni contradiction level); the kernels are
``paper.claims.verdicts_bounds``, the power ``paper.claims.claim_power``.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from paper.claims import claims as C
from paper.claims.claim_power import power_below, power_near, power_trend
from paper.claims.sides import side_below, side_contrast, side_near
from paper.claims.verdicts import NOT_ENOUGH
from paper.claims.verdicts_bounds import (
    NEAR_TOL,
    check_below,
    check_near,
    check_trend,
    trend_weights,
)
from paper.settings import PAPER_TABLE1

PRINT_BOUND = 0.00005  # Table I prints rates as 0.00%: below 0.005% of robot-steps rounds to it
FALLBACK_BOUND = 0.05  # "within the normal search": fewer than 5% of group-steps fall back
PAPER_SLOPE = float(np.dot(trend_weights(list(PAPER_TABLE1)), [v[2] for v in PAPER_TABLE1.values()]))


def claim_collisions_printed(evals: pd.DataFrame, configs: C.Configs = C.PAPER["table1"],
                             run: C.Configs = ()) -> C.Claim:
    claim = C.Claim(
        "collisions_printed", "Collision rate 0.00% at Table I's print precision",
        "Table I prints a collision rate of 0.00% for 40..100 robots at p = 0.2: a rate below "
        f"{100 * PRINT_BOUND:g}% of robot-steps (the literal zero is `no_collisions`).",
        f"One-sample t over per-seed mean collision rates against {100 * PRINT_BOUND:g}%, one-sided, "
        "level 0.0125, per execution mode.")

    def check(rows: pd.DataFrame, contra_alpha: float) -> tuple:
        m = C.seed_means(rows, "collision_rate")
        return (*check_below(m, PRINT_BOUND, "collision rate", contra_alpha),
                power_below(m, PRINT_BOUND, 0.0, "a true rate of 0"), side_below(m, PRINT_BOUND))
    return C._each(claim, configs, run, C._per_filter_mode(C.with_execution(evals), check))


def claim_mean_candidates(evals: pd.DataFrame, configs: C.Configs = C.PAPER["table1"],
                          run: C.Configs = ()) -> C.Claim:
    claim = C.Claim(
        "table1_candidates", "Mean candidates as in Table I",
        "Table I: mean candidates examined per group-step 3.79, 16.44, 24.15, 35.63, 24.68 for "
        "40, 60, 80, 90, 100 robots at p = 0.2.",
        f"Equivalence (two one-sided t over per-seed means, level 0.0125) to the paper's value "
        f"within +-{NEAR_TOL:.0%} of it, per execution mode; team sizes the paper does not print "
        "are not judged.")
    ev = C.with_execution(evals)

    def one(c: tuple, contra_alpha: float) -> list:
        n, p = c
        if n not in PAPER_TABLE1:
            return [(C._cfg(n, p), "-", NOT_ENOUGH, "no value in the paper's Table I", "-")]
        target = PAPER_TABLE1[n][2]

        def check(rows: pd.DataFrame, a: float) -> tuple:
            m = C.seed_means(rows, "mean_candidates")
            return (*check_near(m, target, "mean candidates", a), power_near(m, target),
                    side_near(m, target * (1 - NEAR_TOL), target * (1 + NEAR_TOL)))
        return C._per_filter_mode(ev, check)(c, contra_alpha)
    return C._each(claim, configs, run, one)


def claim_searches_grow(evals: pd.DataFrame, configs: C.Configs = C.PAPER["table1"]) -> C.Claim:
    claim = C.Claim(
        "searches_grow", "Mean searches increase with team size",
        "Sec. IV: \"the mean number of searches generally increases for larger teams\" (Table I, "
        "40..100 robots at p = 0.2).",
        "Welch t on the OLS slope of the per-seed mean candidates on N over the team sizes, "
        "one-sided, level 0.0125, per execution mode.")
    ev = C.with_execution(evals)
    ns = [int(n) for n, _ in configs]
    p = float(configs[0][1]) if configs else 0.2
    label = f"N = {ns[0]}..{ns[-1]}, p = {C.fmt_p(p)}" if ns else "-"

    def one(_: tuple, contra_alpha: float) -> list:
        per_n = [dict(C._hier_modes(ev, n, p)) for n in ns]
        modes = [m for m in C.MODE_ORDER if all(m in d for d in per_n)]
        if not ns or not modes:
            return [(label, "-", NOT_ENOUGH, "a team size lacks data (or the filter is off)", "-")]
        out = []
        for mode in modes:
            groups = [C.seed_means(d[mode], "mean_candidates") for d in per_n]
            out.append((label, mode, *check_trend(groups, ns, "mean candidates", contra_alpha),
                        power_trend(groups, ns, PAPER_SLOPE), side_contrast(groups, list(trend_weights(ns)))))
        return out
    return C._each(claim, [tuple(configs)], (), one)


def claim_normal_search(evals: pd.DataFrame, configs: C.Configs = C.PAPER["table1"],
                        run: C.Configs = ()) -> C.Claim:
    claim = C.Claim(
        "normal_search", "An admissible control is found within the normal search",
        "Sec. IV: \"an admissible control can be identified within the normal safety search\" "
        "(Table I, 40..100 robots at p = 0.2): the filter seldom falls back to the joint Wait.",
        f"One-sample t over per-seed mean fallback rates (group-steps that fell back) against "
        f"{FALLBACK_BOUND:.0%}, one-sided, level 0.0125, per execution mode.")

    def check(rows: pd.DataFrame, contra_alpha: float) -> tuple:
        m = C.seed_means(rows, "fallback_rate")
        return (*check_below(m, FALLBACK_BOUND, "fallback rate", contra_alpha),
                power_below(m, FALLBACK_BOUND, FALLBACK_BOUND / 2, f"a true rate of {FALLBACK_BOUND / 2:.1%}"),
                side_below(m, FALLBACK_BOUND))
    return C._each(claim, configs, run, C._per_filter_mode(C.with_execution(evals), check))
