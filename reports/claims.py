"""Each claim of the paper's Sec. IV checked against the data: holds / does not hold /
not enough data, with the numbers and the test behind the verdict.

A claim is a list of checks, one per configuration the paper names. A claim holds when
every check holds, does not hold when any check fails, and lacks data otherwise (e.g. a
configuration the run does not have). Tests, at level 0.05 / 95%:

* *A above B* (``compare_greater``): with >= 2 seeds on each side, the 95% bootstrap CI
  over seeds of the difference of per-seed means must lie above 0; with a single seed
  on a side, a one-sided Mann-Whitney U test over episodes must give p < 0.05 (this
  ignores seed-to-seed variation, which the report says).
* "Final" training reward = the last ``FINAL_FRAC`` of a cell's training episodes.
* Convergence: ``reports.stats.convergence_test`` on every seed's curve.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from reports.fig3_payload import payload_points
from reports.stats import (
    bootstrap_contrast_ci,
    convergence_test,
    mann_whitney_greater,
    quantile_curve,
)
from reports.store import fmt_p, select
from reports.summary import metric_estimate

HOLDS, FAILS, NO_DATA = "holds", "does not hold", "not enough data"
ALPHA = 0.05
FINAL_FRAC = 0.2
MIN_EPISODES = 5  # fewer samples than this on a side: not enough data
RATIO_TOL = 0.01  # payload ratio "equal" to the bound: within 1%
MAX_CORRECTION = 0.08
GRID = np.linspace(0.0, 100.0, 101)


@dataclass(frozen=True)
class Check:
    """One configuration of a claim: its verdict, the numbers and the test used."""

    config: str
    verdict: str
    numbers: str
    test: str


@dataclass
class Claim:
    key: str
    statement: str  # what the paper says, with its place
    criterion: str  # how the data decides
    checks: list[Check] = field(default_factory=list)

    @property
    def verdict(self) -> str:
        return combine([c.verdict for c in self.checks])


def combine(verdicts: Sequence[str]) -> str:
    """Any failure fails the claim; all holding holds it; otherwise not enough data."""
    if any(v == FAILS for v in verdicts):
        return FAILS
    if verdicts and all(v == HOLDS for v in verdicts):
        return HOLDS
    return NO_DATA


def _g(x: float) -> str:
    return f"{x:.3g}" if np.isfinite(x) else "nan"


# ----------------------------------------------------------------- samples
def final_window(train: pd.DataFrame, frac: float = FINAL_FRAC,
                 metric: str = "team_return") -> dict[str, np.ndarray]:
    """Last ``frac`` of each cell's training episodes (by episode index): cell_id -> (k,)."""
    out = {}
    for cid, g in train.groupby("cell_id", sort=True):
        v = g.sort_values("episode")[metric].to_numpy(dtype=np.float64)
        k = max(1, int(np.floor(frac * len(v))))
        out[str(cid)] = v[-k:]
    return out


def per_cell(evals: pd.DataFrame, metric: str) -> dict[str, np.ndarray]:
    return {str(c): g[metric].to_numpy(dtype=np.float64) for c, g in evals.groupby("cell_id", sort=True)}


def compare_greater(a: dict[str, np.ndarray], b: dict[str, np.ndarray], what: str,
                    seed: int = 0) -> tuple[str, str, str]:
    """Is A above B? ``a``/``b`` map seed cells to samples. Returns (verdict, numbers, test)."""
    if not a or not b:
        return NO_DATA, "missing: " + ", ".join(s for s, d in (("A", a), ("B", b)) if not d), "-"
    if len(a) >= 2 and len(b) >= 2:
        ma = np.array([np.nanmean(v) for v in a.values()])
        mb = np.array([np.nanmean(v) for v in b.values()])
        est, lo, hi = bootstrap_contrast_ci([ma, mb], [1, -1], seed=seed)
        verdict = HOLDS if lo > 0 else FAILS
        nums = (f"{what}: {_g(ma.mean())} vs {_g(mb.mean())}; difference {_g(est)} "
                f"[95% CI {_g(lo)}, {_g(hi)}]")
        return verdict, nums, f"bootstrap CI over seeds ({len(ma)} vs {len(mb)} seeds)"
    xa, xb = np.concatenate(list(a.values())), np.concatenate(list(b.values()))
    xa, xb = xa[np.isfinite(xa)], xb[np.isfinite(xb)]
    if min(xa.size, xb.size) < MIN_EPISODES:
        return NO_DATA, f"only {xa.size} vs {xb.size} episodes", "-"
    pval = mann_whitney_greater(xa, xb)
    est, lo, hi = bootstrap_contrast_ci([xa, xb], [1, -1], seed=seed)
    verdict = HOLDS if np.isfinite(pval) and pval < ALPHA else FAILS
    nums = (f"{what}: {_g(xa.mean())} vs {_g(xb.mean())}; difference {_g(est)} "
            f"[95% CI over episodes {_g(lo)}, {_g(hi)}]; p = {_g(pval)}")
    return verdict, nums, (f"one-sided Mann-Whitney U over episodes ({xa.size} vs {xb.size}; "
                           f"{len(a)} vs {len(b)} seed(s), seed variation not covered)")


# ------------------------------------------------------------------- claims
def claim_hier_above_dec(train: pd.DataFrame, ns: Sequence[int] = (20, 40, 60),
                         p: float = 0.2) -> Claim:
    claim = Claim(
        "hier_above_dec",
        f"Fig. 1(a): for {', '.join(map(str, ns))} robots at p = {fmt_p(p)} the hierarchical method "
        "reaches a higher final episode reward than the fully decentralized baseline.",
        f"Final reward = mean team return over the last {int(FINAL_FRAC * 100)}% of training "
        "episodes; hierarchical above decentralized by the *A above B* test.")
    for n in ns:
        h = final_window(select(train, "hierarchical", n, p))
        d = final_window(select(train, "decentralized", n, p))
        v, nums, test = compare_greater(h, d, "final reward hier vs dec")
        claim.checks.append(Check(f"N = {n}, p = {fmt_p(p)}", v, nums, test))
    return claim


def _gap_samples(train: pd.DataFrame, n: int, p: float) -> tuple[dict[str, np.ndarray], ...]:
    return (final_window(select(train, "hierarchical", n, p)),
            final_window(select(train, "decentralized", n, p)))


def claim_gap_widens(train: pd.DataFrame, large: int = 60, smaller: Sequence[int] = (20, 40),
                     p: float = 0.2) -> Claim:
    claim = Claim(
        "gap_widens",
        f"Fig. 1(a): at {large} robots the decentralized baseline stays considerably lower: the gap "
        f"(hierarchical - decentralized final reward) is larger than at {', '.join(map(str, smaller))}.",
        "Gap(N) = mean final reward hierarchical - decentralized; the 95% bootstrap CI of "
        f"Gap({large}) - Gap(n) must lie above 0 (resampling seeds when every group has >= 2, "
        "else final-window episodes).")
    big = _gap_samples(train, large, p)
    for n in smaller:
        small = _gap_samples(train, n, p)
        groups = [*big, *small]
        cfg = f"Gap({large}) vs Gap({n}), p = {fmt_p(p)}"
        if any(not g for g in groups):
            claim.checks.append(Check(cfg, NO_DATA, "a configuration is missing", "-"))
            continue
        by_seed = all(len(g) >= 2 for g in groups)
        samples = ([np.array([np.nanmean(v) for v in g.values()]) for g in groups] if by_seed
                   else [np.concatenate(list(g.values())) for g in groups])
        if not by_seed and min(s.size for s in samples) < MIN_EPISODES:
            claim.checks.append(Check(cfg, NO_DATA, "too few final-window episodes", "-"))
            continue
        est, lo, hi = bootstrap_contrast_ci(samples, [1, -1, -1, 1])
        g_big = samples[0].mean() - samples[1].mean()
        g_small = samples[2].mean() - samples[3].mean()
        nums = (f"Gap({large}) = {_g(g_big)}, Gap({n}) = {_g(g_small)}; difference {_g(est)} "
                f"[95% CI {_g(lo)}, {_g(hi)}]")
        unit = "seeds" if by_seed else "final-window episodes (seed variation not covered)"
        claim.checks.append(Check(cfg, HOLDS if lo > 0 else FAILS, nums, f"bootstrap CI over {unit}"))
    return claim


def claim_convergence(train: pd.DataFrame, ns: Sequence[int] = (80, 90, 100), p: float = 0.2,
                      frac: float = 0.2, rel_tol: float = 0.2) -> Claim:
    claim = Claim(
        "convergence",
        f"Fig. 1(b): for {', '.join(map(str, ns))} robots at p = {fmt_p(p)} the hierarchical "
        "method's episode reward increases and stabilises (converges at around 1600 of 2000 episodes).",
        f"Per seed, with windows of the first and last {int(frac * 100)}% of training: improved if the "
        "95% bootstrap CI of mean(last) - mean(first) is above 0, and stable if the 95% CI of the "
        "drift over the last window (OLS slope x window length) lies within "
        f"+-{int(rel_tol * 100)}% of that gain (an equivalence test). Holds when every seed passes.")
    for n in ns:
        rows = select(train, "hierarchical", n, p)
        cfg = f"N = {n}, p = {fmt_p(p)}"
        if rows.empty:
            claim.checks.append(Check(cfg, NO_DATA, "configuration missing", "-"))
            continue
        results = []
        for _, g in rows.groupby("cell_id", sort=True):
            results.append(convergence_test(g.sort_values("episode")["team_return"].to_numpy(),
                                            frac=frac, rel_tol=rel_tol))
        if any(r is None for r in results):
            claim.checks.append(Check(cfg, NO_DATA, "too few training episodes for the windows", "-"))
            continue
        ok = [r.converged for r in results if r is not None]
        parts = [f"gain {_g(r.gain)} (CI lo {_g(r.gain_lo)}), drift {_g(r.drift)} "
                 f"[{_g(r.drift_lo)}, {_g(r.drift_hi)}] vs tolerance +-{_g(r.tolerance)}"
                 for r in results if r is not None]
        nums = f"{sum(ok)}/{len(ok)} seeds converged; " + "; ".join(parts[:5])
        if len(parts) > 5:
            nums += f"; ... ({len(parts) - 5} more)"
        claim.checks.append(Check(cfg, HOLDS if all(ok) else FAILS, nums,
                                  f"convergence test per seed (window {results[0].window} episodes)"))
    return claim


def claim_above_ic3net(evals: pd.DataFrame, ns: Sequence[int] = (40, 60),
                       ps: Sequence[float] = (0.2, 0.4, 0.6)) -> Claim:
    claim = Claim(
        "above_ic3net",
        f"Fig. 2: for {', '.join(map(str, ns))} robots and p in {{{', '.join(fmt_p(p) for p in ps)}}} "
        "the hierarchical method achieves higher success rates than IC3Net across the entire range "
        "of evaluation episodes.",
        "Both (i) the hierarchical percentile curve (episodes of all seeds pooled) is nowhere below "
        "IC3Net's on percentiles 0..100, and (ii) the success rate is higher by the *A above B* test.")
    for n in ns:
        for p in ps:
            cfg = f"N = {n}, p = {fmt_p(p)}"
            h, i = select(evals, "hierarchical", n, p), select(evals, "ic3net", n, p)
            if h.empty or i.empty:
                claim.checks.append(Check(cfg, NO_DATA, "configuration missing", "-"))
                continue
            v, nums, test = compare_greater(per_cell(h, "success_rate"), per_cell(i, "success_rate"),
                                            "mean success rate hier vs IC3Net")
            if v == NO_DATA:
                claim.checks.append(Check(cfg, v, nums, test))
                continue
            diff = (quantile_curve(h["success_rate"].to_numpy(), GRID)
                    - quantile_curve(i["success_rate"].to_numpy(), GRID))
            dominates = bool(np.all(diff >= -1e-12))
            nums = (f"{nums}; curve difference min {_g(diff.min())}, above on "
                    f"{np.mean(diff > 1e-12) * 100:.0f}% of percentiles")
            claim.checks.append(Check(cfg, v if dominates else FAILS, nums,
                                      f"percentile-curve dominance + {test}"))
    return claim


def claim_payload_ratio(evals: pd.DataFrame) -> Claim:
    claim = Claim(
        "payload_ratio",
        "Fig. 3 / Sec. III-A: the measured payload ratio C_hier / C_dec equals the analytical "
        "(Z-1)/(N-1) (C_hier <= N(Z-1)d_m): O(NZ) instead of O(N^2) communication.",
        f"At every team size of the run: measured ratio within {RATIO_TOL:.0%} of (Z-1)/(N-1) and "
        "no evaluation episode above the bound (payload is counted, not sampled: no test needed).")
    pts = payload_points(evals)
    for _, r in pts.iterrows():
        cfg = f"N = {r['n_robots']}, Z = {r['groups']}"
        if r["n_robots"] < 2 or not np.isfinite(r["ratio"]):
            claim.checks.append(Check(cfg, NO_DATA, "ratio undefined", "-"))
            continue
        rel = abs(r["ratio"] - r["bound"]) / r["bound"] if r["bound"] > 0 else np.inf
        within = bool(r["ratio_max"] <= r["bound"] * (1 + 1e-9))
        v = HOLDS if rel <= RATIO_TOL and within else FAILS
        nums = (f"C_hier = {_g(r['c_hier'])}, C_dec = {_g(r['c_dec'])} ({r['c_dec_source']}); ratio "
                f"{r['ratio']:.4f} vs bound {r['bound']:.4f} (relative difference {rel:.2%}); "
                f"largest episode ratio {r['ratio_max']:.4f}")
        claim.checks.append(Check(cfg, v, nums, f"exact comparison over {r['episodes']} episodes"))
    if pts.empty:
        claim.checks.append(Check("any N", NO_DATA, "no hierarchical evaluation rows", "-"))
    return claim


def claim_safety(evals: pd.DataFrame, ns: Sequence[int] = (40, 60, 80, 90, 100), p: float = 0.2,
                 max_correction: float = MAX_CORRECTION) -> Claim:
    claim = Claim(
        "safety",
        f"Table I: for {', '.join(map(str, ns))} robots at p = {fmt_p(p)}, no collisions are observed "
        f"in evaluation and the safety filter modifies fewer than {max_correction:.0%} of the controls.",
        f"Zero colliding robot-steps in every evaluation episode, and the 95% bootstrap CI of the mean "
        f"correction rate (over seeds, or episodes with one seed) entirely below {max_correction:.0%}.")
    for n in ns:
        cfg = f"N = {n}, p = {fmt_p(p)}"
        rows = select(evals, "hierarchical", n, p)
        if rows.empty:
            claim.checks.append(Check(cfg, NO_DATA, "configuration missing", "-"))
            continue
        if not rows["safety_filter"].all():
            claim.checks.append(Check(cfg, NO_DATA, "safety filter off in some cells", "-"))
            continue
        coll = rows["collision_rate"].to_numpy(dtype=np.float64)
        n_coll_eps = int((coll > 0).sum())
        mean, lo, hi, unit = metric_estimate(rows, "correction_rate")
        ok = n_coll_eps == 0 and np.isfinite(hi) and hi < max_correction
        nums = (f"episodes with a collision: {n_coll_eps}/{len(rows)} (mean collision rate "
                f"{np.nanmean(coll):.3%}); correction rate {mean:.2%} [95% CI {lo:.2%}, {hi:.2%}]")
        claim.checks.append(Check(cfg, HOLDS if ok else FAILS, nums,
                                  f"count of collisions; bootstrap CI over {unit}"))
    return claim


def all_claims(train: pd.DataFrame, evals: pd.DataFrame) -> list[Claim]:
    """Every claim of Sec. IV at the paper's configurations."""
    return [claim_hier_above_dec(train), claim_gap_widens(train), claim_convergence(train),
            claim_above_ic3net(evals), claim_payload_ratio(evals), claim_safety(evals)]


def _esc(s: str) -> str:
    return s.replace("|", "\\|")


def claims_markdown(claims: Sequence[Claim]) -> str:
    lines = ["# Claims of the paper's Sec. IV against this run", "",
             "Verdicts: **holds**, **does not hold**, or **not enough data** (a configuration "
             "the run lacks, or too few episodes). Level 0.05 / 95% intervals throughout.", "",
             "| claim | verdict |", "|---|---|"]
    lines += [f"| [{c.key}](#{c.key}) | **{c.verdict}** |" for c in claims]
    for c in claims:
        lines += ["", f"## {c.key}", "", f"*Paper:* {c.statement}", "",
                  f"*Test:* {c.criterion}", "", f"**Verdict: {c.verdict}**", "",
                  "| configuration | verdict | numbers | test |", "|---|---|---|---|"]
        lines += [f"| {_esc(k.config)} | {k.verdict} | {_esc(k.numbers)} | {_esc(k.test)} |"
                  for k in c.checks]
    return "\n".join(lines) + "\n"
