"""Claims of the methods a run brings: "M above each baseline".

For every method of the run that is neither the paper's method nor one of its baselines
(``Method.paper_role`` "", e.g. a user's plugin; a method that cannot be resolved here counts
as one), one claim: M's mean success is above each baseline's, at every configuration
(N, p) both have done cells at and every execution-mode pair (shared modes; a planner's one
mode against each mode of the other side). Each check is ``check_greater`` on per-seed mean
success (Welch t, one-sided, support at ``TEST_ALPHA``), the claim's k checks decided with
Bonferroni as every paper claim (``claims.decide_scope``), and beside each its power to detect
+``EFFECT_SUCCESS`` success. The checks are of scope "run": the claim is the run's, not the
paper's. ``bench calibrate`` calibrates this family with the paper's method standing in for M
(paper/claims/calibrate_data.py).

May import: algorithms.base / algorithms.registry (the roles), paper.claims, reports.data,
reports.figures.plotting (labels and their order).
"""
from __future__ import annotations

from collections.abc import Iterator

import pandas as pd

from algorithms.base import BASELINE, REFERENCE
from paper.claims.claim_power import power_success
from paper.claims.claims import (
    Claim,
    _cfg,
    _mode_key,
    decide_scope,
    mode_pairs,
    run_configs,
    seed_means,
    with_execution,
)
from paper.claims.power import NO_POWER
from paper.claims.sides import side_contrast
from paper.claims.verdicts import NOT_ENOUGH, TEST_ALPHA, check_greater
from paper.roles import role
from reports.data.store import select
from reports.figures.plotting import label_order, method_label

__all__ = ["SCOPE", "claim_above_baselines", "method_claims", "methods_by_role", "paired_rows", "paper_role",
           "planner_pairs"]

SCOPE = "run"


def paper_role(method: str) -> str:
    """The method's role in the paper (``paper.roles``): REFERENCE, BASELINE or ""."""
    return role(method)


def _ordered(methods: set[str]) -> list[str]:
    return sorted(methods, key=lambda m: (label_order(method_label(m)), m))


def methods_by_role(evals: pd.DataFrame) -> tuple[list[str], list[str]]:
    """(the run's baselines, the run's own methods: neither the paper's nor a baseline),
    each in legend order."""
    methods = set(map(str, evals["method"].unique())) if len(evals) else set()
    roles = {m: paper_role(m) for m in methods}
    return (_ordered({m for m, r in roles.items() if r == BASELINE}),
            _ordered({m for m, r in roles.items() if r not in (REFERENCE, BASELINE)}))


def planner_pairs(a: pd.DataFrame, b: pd.DataFrame) -> list[tuple[str, pd.DataFrame, pd.DataFrame]]:
    """``mode_pairs``, else, when one side has one mode only (a planner), that mode against
    each mode of the other side ("argmax vs planner")."""
    pairs = mode_pairs(a, b)
    ma, mb = sorted(set(a["execution"]), key=_mode_key), sorted(set(b["execution"]), key=_mode_key)
    if pairs or not (len(ma) == 1 or len(mb) == 1):
        return pairs
    return [(f"{x} vs {y}", a[a["execution"] == x], b[b["execution"] == y]) for x in ma for y in mb]


def paired_rows(evals: pd.DataFrame, method: str, baselines: list[str]
                ) -> Iterator[tuple[str, int, float, str, pd.DataFrame, pd.DataFrame]]:
    """(baseline, N, p, execution label, M's rows, the baseline's rows) of every check of
    "``method`` above each of ``baselines``", in order: baseline, configuration, mode.
    ``evals`` must have its ``execution`` column (``with_execution``)."""
    for b in baselines:
        for n, p in run_configs(evals, (method, b)):
            yield from ((b, n, p, mode, mm, bb)
                        for mode, mm, bb in planner_pairs(select(evals, method, n, p), select(evals, b, n, p)))


def claim_above_baselines(evals: pd.DataFrame, method: str, baselines: list[str]) -> Claim:
    """"``method`` above each baseline": one check per baseline, configuration and mode pair."""
    ev = with_execution(evals)
    who = method_label(method)
    claim = Claim(
        f"above_baselines_{method}", f"{who} above each baseline (mean success)",
        f"{who} is a method of this run, neither the paper's nor a baseline: its success rate is "
        f"higher than that of each baseline of the run ({', '.join(map(method_label, baselines))}) at every "
        "configuration both ran, per execution mode.",
        "Per seed, the mean success rate over the evaluation episodes; Welch t over seeds, one-sided, "
        f"level {TEST_ALPHA:g}; contradicted at {TEST_ALPHA:g} / k over the claim's k checks (Bonferroni).",
        home=SCOPE)
    checks = list(paired_rows(ev, method, baselines))

    def one(c: tuple, contra_alpha: float) -> list:
        b, n, p, mode, mm, bb = c
        a, z = seed_means(mm, "success_rate"), seed_means(bb, "success_rate")
        v, nums, test = check_greater(a, z, "mean success", contra_alpha)
        return [(f"vs {method_label(b)}, {_cfg(n, p)}", mode, v, nums, test,
                 power_success(a, z) if v != NOT_ENOUGH else NO_POWER, side_contrast([a, z], [1.0, -1.0]))]
    return decide_scope(claim, SCOPE, checks, one)


def method_claims(evals: pd.DataFrame) -> list[Claim]:
    """One "above each baseline" claim per method of the run's own, when the run has a
    baseline; none otherwise."""
    baselines, own = methods_by_role(evals)
    return [claim_above_baselines(evals, m, baselines) for m in own] if baselines else []
