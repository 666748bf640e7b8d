"""Each claim of the paper's Sec. IV (and two facts about its settings) checked against
the data, one check per configuration and execution mode.

Verdicts (docs/decisions/0040, 0041): **supported** (significant at level 0.0125 in the
paper's direction), **contradicted** (significant in the opposite direction),
**undecided** (neither; a contradiction counts at 0.0125 / k for a claim of k checks, so
that its false-contradiction rate is <= 0.05 too), **not enough seeds** (fewer than ``MIN_SEEDS`` seeds on a
side, or the configuration is missing). Two checks are not statistical: the payload
ratio is **verified by construction** (the bench counts the scalars with the paper's
formula), and Lemma 1's candidate bound is arithmetic on the settings.

This module turns the store's tables into per-seed arrays, per configuration and
execution mode, and hands them to the test kernels of ``paper.claims.verdicts``. The seed is
the unit: every test takes one number per seed (a per-seed mean), never pooled episodes,
and is a Welch / one-sample t test (``reports.stats``). Its rate of
``supported`` under the null and its power are measured by ``bench calibrate``
(``paper.claims.calibrate``), which feeds simulated tables through these same functions.
A claim's verdict combines its checks: any contradicted -> contradicted (each check
decided at 0.0125 / k, Bonferroni over the claim's k checks); all supported -> supported
(each at 0.0125, an intersection-union test); else undecided if any check is, else not
enough seeds.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from algorithms.hierarchical.safety_filter import lemma1_count
from paper.claims.claim_power import (
    power_below,
    power_convergence,
    power_curves,
    power_gap,
    power_greater,
)
from paper.claims.pooled import Pooled, sign_test
from paper.claims.power import COULD_NOT, LOW, NO_POWER, Power
from paper.claims.sides import (
    NO_SIDE,
    SPANS_BOTH,
    Side,
    side_below,
    side_contrast,
    side_convergence,
    side_curves,
)
from paper.claims.verdicts import (
    BAND_TOL,
    BY_CONSTRUCTION,
    CONDITION_NOT_MET,
    CONTRADICTED,
    CONV_REL_TOL,
    FINAL_FRAC,
    INCONCLUSIVE,
    MAX_CORRECTION,
    NOT_ENOUGH,
    TEST_ALPHA,
    check_collisions,
    check_convergence,
    check_corrections,
    check_curves,
    check_gap,
    check_greater,
    combine,
    per_seed_means,
    seeds_msg,
)
from paper.data.payload import payload_points
from paper.settings import (
    PAPER_C_MAX,
    PAPER_FIG1_P,
    PAPER_FIG1A_N,
    PAPER_FIG1B_N,
    PAPER_FIG2_N,
    PAPER_FIG2_P,
    PAPER_GROUPS,
    PAPER_N,
    PAPER_SEARCH_RADIUS,
    PAPER_TABLE1,
    PAPER_TABLE1_N,
    PAPER_TABLE1_P,
)
from reports.data.store import fmt_p, select

RATIO_TOL = 0.01  # payload ratio "equal" to the bound: within 1%
TRAINING = "training (sampled)"
# Execution mode of rows from stores without an ``execution`` column: each method's old default.
DEFAULT_EXECUTION = {"hierarchical": "argmax", "pibt": "planner"}
MODE_ORDER = ("argmax", "sample", "sample@0.5")
# The paper's configurations (Sec. IV) and safety-filter settings (Sec. IV: Z = 4, L = 2, C_max = 500; |U| = 5).
PAPER: dict[str, tuple[tuple[Any, ...], ...]] = {"fig1a": tuple((n, PAPER_FIG1_P) for n in PAPER_FIG1A_N),
         "gap": tuple((PAPER_FIG1A_N[-1], n, PAPER_FIG1_P) for n in PAPER_FIG1A_N[:-1]),
         "fig1b": tuple((n, PAPER_FIG1_P) for n in PAPER_FIG1B_N),
         "fig2": tuple((n, p) for n in PAPER_FIG2_N for p in PAPER_FIG2_P),
         "table1": tuple((n, PAPER_TABLE1_P) for n in PAPER_TABLE1_N),
         "lemma1": tuple((n, PAPER_GROUPS, PAPER_SEARCH_RADIUS, PAPER_C_MAX) for n in PAPER_N)}


@dataclass(frozen=True)
class Check:
    """One configuration (and execution mode) of a claim: verdict, numbers, test used.
    ``scope`` is "paper" (the paper's configuration) or "run" (``--claims-at run``)."""

    config: str
    verdict: str
    numbers: str
    test: str
    execution: str = "-"
    scope: str = "paper"
    power: float = float("nan")  # power to detect the stated effect (paper.claims.claim_power)
    power_text: str = "-"  # that power, its effect and the seeds 80% power would need
    side: Side = NO_SIDE  # the estimate, its printed interval and the claim's region (paper.claims.sides)

    @property
    def verdict_words(self) -> str:
        """The verdict as the page prints it. An undecided check says which way its estimate
        points and what its interval excludes; only one whose interval spans both the claim
        and its negation, with power under 50%, says the design could not have decided it."""
        if self.verdict != INCONCLUSIVE or not self.side.known:
            return self.verdict
        if self.side.excludes == SPANS_BOTH and self.power < LOW:
            return f"{COULD_NOT} (points {self.side.points})"
        if not self.side.excludes:
            return f"{self.verdict}: points {self.side.points}"
        what = "spans both the claim and its negation" if self.side.excludes == SPANS_BOTH \
            else f"excludes {self.side.excludes}"
        return f"{self.verdict}: points {self.side.points}; its 95% CI {what}"


@dataclass
class Claim:
    key: str
    name: str  # readable name
    statement: str  # what the paper says, with its place
    criterion: str  # how the data decides
    checks: list[Check] = field(default_factory=list)
    home: str = "paper"  # the scope whose checks give the claim's verdict ("run": a method of the run's own)

    def verdict_at(self, scope: str) -> str | None:
        """Combined verdict of the checks of ``scope``; None if it has none."""
        vs = [c.verdict for c in self.checks if c.scope == scope]
        return combine(vs) if vs else None

    @property
    def verdict(self) -> str:
        """The verdict at the claim's home scope (the paper's configurations; a run
        method's claim: the run's), every execution mode."""
        return self.verdict_at(self.home) or NOT_ENOUGH

    def pooled(self, scope: str | None = None) -> Pooled:
        """The sign test across the checks of ``scope`` (default the claim's home)
        (``paper.claims.pooled``): the directions their estimates point."""
        scope = self.home if scope is None else scope
        return sign_test([c.side.points for c in self.checks if c.scope == scope and c.verdict != NOT_ENOUGH
                          and c.side.one_sided])

    def verdict_by_mode(self, scope: str | None = None) -> dict[str, str]:
        """Combined verdict per execution mode of the checks of ``scope`` (default the
        claim's home; modes in first appearance order; "-" for checks without data)."""
        scope = self.home if scope is None else scope
        modes: dict[str, list[str]] = {}
        for c in self.checks:
            if c.scope == scope:
                modes.setdefault(c.execution, []).append(c.verdict)
        return {m: combine(vs) for m, vs in modes.items()}


def _g(x: float) -> str:
    return f"{x:.3g}"  # nan and inf print as themselves


def _cfg(n: int, p: float) -> str:
    return f"N = {n}, p = {fmt_p(p)}"


# ----------------------------------------------------------------- samples
def per_cell(rows: pd.DataFrame, metric: str) -> list[np.ndarray]:
    """One array per cell (seed), sorted by cell_id, of ``metric`` in episode order."""
    if rows.empty:
        return []
    cid = rows["cell_id"].to_numpy().astype(str)
    order = np.lexsort((rows["episode"].to_numpy(), cid))
    cid, v = cid[order], rows[metric].to_numpy(dtype=np.float64)[order]
    _, starts = np.unique(cid, return_index=True)
    return np.split(v, starts[1:])


def final_means(train: pd.DataFrame, frac: float = FINAL_FRAC, metric: str = "team_return") -> np.ndarray:
    """(S,) per-seed mean of ``metric`` over each cell's last ``frac`` of training episodes."""
    return np.array([np.nanmean(v[len(v) - max(1, int(np.floor(frac * len(v)))):])
                     for v in per_cell(train, metric)], dtype=np.float64)


def seed_means(rows: pd.DataFrame, metric: str) -> np.ndarray:
    """(S,) per-seed (per-cell) mean of an evaluation metric."""
    return per_seed_means(per_cell(rows, metric))


def with_execution(evals: pd.DataFrame) -> pd.DataFrame:
    """``evals`` with an ``execution`` column; rows of stores without one get their
    method's old default mode (hierarchical argmax, PIBT planner, others sample)."""
    method = evals["method"].to_numpy().astype(str)
    default = np.full(len(evals), "sample", dtype=object)
    for m, mode in DEFAULT_EXECUTION.items():
        default[method == m] = mode
    if "execution" not in evals.columns:
        return evals.assign(execution=default)
    ex = evals["execution"].to_numpy(dtype=object)
    missing = pd.isna(ex) | (ex.astype(str) == "")
    return evals.assign(execution=np.where(missing, default, ex).astype(str))


def _mode_key(m: str) -> tuple[int, str]:
    return (MODE_ORDER.index(m) if m in MODE_ORDER else len(MODE_ORDER), m)


def mode_pairs(a: pd.DataFrame, b: pd.DataFrame) -> list[tuple[str, pd.DataFrame, pd.DataFrame]]:
    """(label, a rows, b rows) per execution mode both sides have; when they share none
    and each has exactly one (a store from before execution modes), that one pair."""
    ma, mb = set(a["execution"]), set(b["execution"])
    common = sorted(ma & mb, key=_mode_key)
    if common:
        return [(m, a[a["execution"] == m], b[b["execution"] == m]) for m in common]
    if len(ma) == 1 and len(mb) == 1:
        return [(f"{next(iter(ma))} vs {next(iter(mb))}", a, b)]
    return []


def _modes(rows: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    return [(m, rows[rows["execution"] == m]) for m in sorted(set(rows["execution"]), key=_mode_key)]


# ------------------------------------------------------------------- claims
Configs = Sequence[tuple]
# (config label, execution, verdict, numbers, test[, power[, side]]): one check of ``_each``'s fn
CheckRow = tuple[str, str, str, str, str] | tuple[str, str, str, str, str, Power] | \
    tuple[str, str, str, str, str, Power, Side]


def _each(claim: Claim, paper: Configs, run: Configs,
          fn: Callable[[tuple, float], list[CheckRow]]) -> Claim:
    """``decide_scope`` at the paper's configurations, then at the run's own ones that are
    not paper ones (``--claims-at run``)."""
    decide_scope(claim, "paper", paper, fn)
    return decide_scope(claim, "run", [c for c in run if c not in paper], fn)


def decide_scope(claim: Claim, scope: str, configs: Configs,
                 fn: Callable[[tuple, float], list[CheckRow]]) -> Claim:
    """Append fn(config, contra_alpha) -> [(config label, execution, verdict, numbers,
    test[, power[, side]])] as the checks of ``scope`` (``power`` a ``paper.claims.power.Power``,
    ``side`` a ``paper.claims.sides.Side``, only with a verdict that has seeds).

    A scope's k checks decide one claim, and one contradicted check contradicts it, so
    each check may contradict only at TEST_ALPHA / k (Bonferroni; ``paper.claims.verdicts``):
    a first pass counts the checks, the second decides at that level."""
    first = [fn(c, TEST_ALPHA) for c in configs]
    k = sum(len(rows) for rows in first)
    decided = first if k <= 1 else [fn(c, TEST_ALPHA / k) for c in configs]  # one check: already at TEST_ALPHA
    for rows in decided:
        for label, ex, v, nums, test, *extra in rows:
            pw: Power = extra[0] if extra and v != NOT_ENOUGH else NO_POWER  # type: ignore[assignment]  # CheckRow's 6th
            side: Side = extra[1] if len(extra) > 1 and v != NOT_ENOUGH else NO_SIDE  # type: ignore[assignment]  # 7th
            claim.checks.append(Check(label, v, nums, test, ex, scope, pw.power, pw.text(), side))
    return claim


def run_configs(df: pd.DataFrame, methods: Sequence[str]) -> list[tuple[int, float]]:
    """(N, p) pairs at which every one of ``methods`` has rows, sorted."""
    sets = [set(zip(select(df, m)["n_robots"].astype(int), select(df, m)["loss_p"].astype(float),
                    strict=True)) for m in methods]
    return sorted(set.intersection(*sets)) if sets else []


def claim_hier_above_dec(train: pd.DataFrame, configs: Configs = PAPER["fig1a"], run: Configs = ()) -> Claim:
    claim = Claim(
        "hier_above_dec", "Hierarchical above decentralized (final training reward)",
        "Fig. 1(a): for 20, 40, 60 robots at p = 0.2 the hierarchical method reaches a higher final "
        "episode reward than the fully decentralized baseline.",
        f"Per seed, the mean team return over the last {FINAL_FRAC:.0%} of training; Welch t over "
        "seeds, one-sided, level 0.0125.")

    def one(c: tuple, contra_alpha: float) -> list:
        n, p = c
        a, b = final_means(select(train, "hierarchical", n, p)), final_means(select(train, "decentralized", n, p))
        v, nums, test = check_greater(a, b, "final reward", contra_alpha)
        return [(_cfg(n, p), TRAINING, v, nums, test, power_greater(a, b), side_contrast([a, b], [1.0, -1.0]))]
    return _each(claim, configs, run, one)


def claim_gap_widens(train: pd.DataFrame, configs: Configs = PAPER["gap"], run: Configs = ()) -> Claim:
    claim = Claim(
        "gap_widens", "Gap to decentralized widest at 60 robots",
        "Fig. 1(a): at 60 robots the decentralized baseline stays considerably lower: the gap "
        "(hierarchical - decentralized final reward) is larger than at 20 and 40.",
        "Gap(N) = mean final reward hierarchical - decentralized; Welch t on the contrast "
        "Gap(large) - Gap(small) of four groups of per-seed means, one-sided, level 0.0125.")

    def one(c: tuple, contra_alpha: float) -> list:
        large, small, p = c
        groups = [final_means(select(train, m, n, p))
                  for n in (large, small) for m in ("hierarchical", "decentralized")]
        v, nums, test = check_gap(groups, large, small, contra_alpha)
        return [(f"Gap({large}) vs Gap({small}), p = {fmt_p(p)}", TRAINING, v, nums, test, power_gap(groups),
                 side_contrast(groups, [1.0, -1.0, -1.0, 1.0]))]
    return _each(claim, configs, run, one)


def claim_convergence(train: pd.DataFrame, configs: Configs = PAPER["fig1b"], run: Configs = ()) -> Claim:
    claim = Claim(
        "convergence", "Hierarchical training converges",
        "Fig. 1(b): for 80, 90, 100 robots at p = 0.2 the hierarchical method's episode reward "
        "increases and stabilises (converges at around 1600 of 2000 episodes).",
        f"Per seed: gain = mean(last {FINAL_FRAC:.0%}) - mean(first {FINAL_FRAC:.0%}) of training, "
        "drift = OLS slope over the last window x its length. Supported when, over seeds, the gain "
        f"is > 0 and |drift| < {CONV_REL_TOL:g} x gain (equivalence), each by a one-sample t at 0.0125; "
        "contradicted when the gain is < 0 or the drift is beyond the tolerance (still rising or "
        "collapsing) significantly.")

    def one(c: tuple, contra_alpha: float) -> list:
        n, p = c
        curves = per_cell(select(train, "hierarchical", n, p), "team_return")
        v, nums, test = check_convergence(curves, contra_alpha=contra_alpha)
        pw = power_convergence(curves, CONV_REL_TOL, FINAL_FRAC) if v != NOT_ENOUGH else NO_POWER
        return [(_cfg(n, p), TRAINING, v, nums, test, pw, side_convergence(curves))]
    return _each(claim, configs, run, one)


def claim_above_ic3net(evals: pd.DataFrame, configs: Configs = PAPER["fig2"], run: Configs = ()) -> Claim:
    claim = Claim(
        "above_ic3net", "Hierarchical above IC3Net across evaluation episodes",
        "Fig. 2: for 40 and 60 robots and p in {0.2, 0.4, 0.6} the hierarchical method achieves "
        "higher success rates than IC3Net across the entire range of evaluation episodes.",
        "Per seed, the success-rate quantile curve at percentiles 10..90; supported when the mean "
        f"success is higher (Welch t) and the hierarchical curve is nowhere more than {BAND_TOL:g} "
        "below IC3Net's (one-sided simultaneous band), per execution mode.")
    ev = with_execution(evals)

    def one(c: tuple, contra_alpha: float) -> list:
        n, p = c
        h, i = select(ev, "hierarchical", n, p), select(ev, "ic3net", n, p)
        pairs = mode_pairs(h, i) if len(h) and len(i) else []
        if not pairs:
            return [(_cfg(n, p), "-", NOT_ENOUGH, seeds_msg(h["cell_id"].nunique(),
                                                             i["cell_id"].nunique()), "-")]
        out = []
        for mode, hh, ii in pairs:
            hs, is_ = per_cell(hh, "success_rate"), per_cell(ii, "success_rate")
            v, nums, test = check_curves(hs, is_, contra_alpha)
            out.append((_cfg(n, p), mode, v, nums, test,
                        power_curves(hs, is_) if v != NOT_ENOUGH else NO_POWER, side_curves(hs, is_)))
        return out
    return _each(claim, configs, run, one)


def _hier_modes(evals: pd.DataFrame, n: int, p: float) -> list[tuple[str, pd.DataFrame]]:
    rows = select(evals, "hierarchical", n, p)
    if "safety_filter" in rows.columns:
        rows = rows[rows["safety_filter"].astype(bool)]
    return _modes(rows) if len(rows) else []


def claim_no_collisions(evals: pd.DataFrame, configs: Configs = PAPER["table1"], run: Configs = ()) -> Claim:
    claim = Claim(
        "no_collisions", "Zero collisions, literally (safety filter on)",
        "Table I: for 40..100 robots at p = 0.2 no collisions are observed in the evaluation "
        "episodes. Not guaranteed: Proposition 2 assumes received positions, and under loss the "
        "filter uses predicted ones (issue 18), so the number is the measured collision rate.",
        "Against a literal zero: supported iff no evaluation episode of >= 3 seeds has a "
        "collision; any collision contradicts; per execution mode. The rate at the paper's print "
        "precision (0.00%) is `collisions_printed`.")
    return _each(claim, configs, run, _per_filter_mode(
        with_execution(evals), lambda rows, _: check_collisions(per_cell(rows, "collision_rate"))))


def claim_few_corrections(evals: pd.DataFrame, configs: Configs = PAPER["table1"], run: Configs = ()) -> Claim:
    claim = Claim(
        "few_corrections", "Safety filter modifies fewer than 8% of controls",
        f"Table I: for 40..100 robots at p = 0.2 the filter modifies fewer than {MAX_CORRECTION:.0%} "
        "of the proposed robot controls.",
        f"One-sample t over per-seed mean correction rates against {MAX_CORRECTION:.0%}, one-sided, "
        "level 0.0125, per execution mode.")
    ev = with_execution(evals)

    def one(c: tuple, contra_alpha: float) -> list:
        paper = c[0] in PAPER_TABLE1
        truth = PAPER_TABLE1[c[0]][1] if paper else MAX_CORRECTION / 2
        words = f"a true rate of {truth:.2%}" + (" (the paper's)" if paper else "")

        def check(rows: pd.DataFrame, a: float) -> tuple:
            m = seed_means(rows, "correction_rate")
            return (*check_corrections(m, contra_alpha=a), power_below(m, MAX_CORRECTION, truth, words),
                    side_below(m, MAX_CORRECTION))
        return _per_filter_mode(ev, check)(c, contra_alpha)
    return _each(claim, configs, run, one)


def _per_filter_mode(ev: pd.DataFrame, check: Callable[[pd.DataFrame, float], tuple],
                     ) -> Callable[[tuple, float], list]:
    """A per-configuration check for ``_each``: ``check(rows, contra_alpha)`` on the
    hierarchical rows (filter on) of each execution mode at (N, p), or 'not enough seeds'
    when there are none."""
    def one(c: tuple, contra_alpha: float) -> list:
        n, p = c
        modes = _hier_modes(ev, n, p)
        if not modes:
            return [(_cfg(n, p), "-", NOT_ENOUGH, "configuration missing (or filter off)", "-")]
        return [(_cfg(n, p), mode, *check(rows, contra_alpha)) for mode, rows in modes]
    return one


def claim_payload_ratio(evals: pd.DataFrame) -> Claim:
    claim = Claim(
        "payload_ratio", "Payload ratio equals (Z-1)/(N-1)",
        "Fig. 3 / Sec. III-A: the payload ratio C_hier / C_dec equals the analytical "
        "(Z-1)/(N-1) (C_hier <= N(Z-1)d_m): O(NZ) instead of O(N^2) communication.",
        "Verified by construction: the channel counts the scalars it sends with the paper's formula, "
        f"so the check (ratio within {RATIO_TOL:.0%} of the bound, no episode above it) cannot fail "
        "unless the counting is broken. The payload is the formula's count per step (d_m scalars "
        "per robot per link sent), not measured from the bytes of the messages. At every team size "
        "of the run.")
    pts = payload_points(evals)
    for _, r in pts.iterrows():
        cfg = f"N = {r['n_robots']}, Z = {r['groups']}"
        if r["n_robots"] < 2 or not np.isfinite(r["ratio"]):
            claim.checks.append(Check(cfg, NOT_ENOUGH, "ratio undefined", "-"))
            continue
        rel = abs(r["ratio"] - r["bound"]) / r["bound"] if r["bound"] > 0 else np.inf
        ok = rel <= RATIO_TOL and bool(r["ratio_max"] <= r["bound"] * (1 + 1e-9))
        nums = (f"formula count C_hier = {_g(r['c_hier'])}, C_dec = {_g(r['c_dec'])} ({r['c_dec_source']}); ratio "
                f"{r['ratio']:.4f} vs bound {r['bound']:.4f} (relative difference {rel:.2%}); "
                f"largest episode ratio {r['ratio_max']:.4f}")
        claim.checks.append(Check(cfg, BY_CONSTRUCTION if ok else CONTRADICTED, nums,
                                  f"the formula's count over {r['episodes']} episodes (not measured from messages)"))
    if pts.empty:
        claim.checks.append(Check("any N", NOT_ENOUGH, "no hierarchical evaluation rows", "-"))
    return claim


def claim_lemma1(configs: Configs = PAPER["lemma1"], run: Configs = ()) -> Claim:
    """Lemma 1 at the given (N, Z, L, C_max): largest group n_z = ceil(N / Z) (robot i in
    group i mod Z, envs/channel.py)."""
    claim = Claim(
        "lemma1_budget", "Lemma 1's guarantee applies at the paper's settings (C_max covers the candidates)",
        "Lemma 1 (lemma:safety_bound): if C_max >= sum_{d<=L} C(n_z, d)(m-1)^d the filter examines "
        "every candidate within radius L. The paper uses Z = 4, L = 2, C_max = 500, m = 5.",
        "Arithmetic on the settings with the largest group n_z = ceil(N/Z): verified when the bound is "
        "<= C_max; **condition not met** (the lemma's premise fails, so its guarantee does not "
        "apply; nothing in the data is contradicted) when it exceeds C_max.")

    def one(c: tuple, _: float) -> list:  # arithmetic: no error to control
        n, z, radius, c_max = c
        n_z = -(-n // z)
        b = lemma1_count(n_z, radius)
        v = BY_CONSTRUCTION if b <= c_max else CONDITION_NOT_MET
        return [(f"N = {n}, Z = {z}, L = {radius}, C_max = {c_max}", "-", v,
                 f"n_z = {n_z}: bound {b:,} {'<=' if b <= c_max else '>'} C_max = {c_max}",
                 "arithmetic (no data)")]
    return _each(claim, configs, run, one)
