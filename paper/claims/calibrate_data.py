"""``bench calibrate`` on the committed reproduction's own spread.

Every check of every statistical claim is simulated at its real seed counts (5 vs 3 where
the store has them) and its real contradiction level 0.05 / k, and every claim as a whole
(its k checks at once). The claims of a run's own methods, "M above each baseline"
(``paper.claims.method_claims``), are the family ``above_baselines``: the paper's method in
M's place against each baseline at every configuration and mode pair the store has. Each group's
per-seed values are drawn as ``mu + sd z``: ``mu``
put on the claim's boundary (the null) or at the stated effect, ``sd`` the group's own
observed seed spread, and ``z`` either resampled from the claim's pooled standardized
per-seed residuals (the data's own shape: its skew and collapsed seeds; a smoothed
bootstrap, since 3-seed residuals take few distinct values and plain resampling would
tie seeds far more often than the data does) or standard normal (the stated
parametric case). Per-seed statistics are what every claim test
decides on (a mean per seed; a quantile curve per seed; a seed's gain and drift), so the
budget of training and evaluation episodes is in the data's own spread.

The tests are re-stated vectorized over simulations (numpy over (sims, seeds)) and agree
verdict for verdict with ``paper.claims.verdicts`` / ``paper.claims.verdicts_bounds``
(tests/reports/test_calibrate_data.py). Checks of one claim are drawn independently
(its execution modes share seeds in the store, a positive dependence under which the
Bonferroni level is conservative). Verdict codes: 1 supported, 0 undecided,
-1 contradicted.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats as sps

from algorithms.base import REFERENCE
from paper.claims import claims as C
from paper.claims import method_claims as MC
from paper.claims.claim_power import EFFECT_SUCCESS, REWARD_FRAC
from paper.claims.table1_claims import FALLBACK_BOUND, PAPER_SLOPE, PRINT_BOUND
from paper.claims.verdicts import (
    BAND_PCT,
    BAND_TOL,
    CONV_REL_TOL,
    FINAL_FRAC,
    MAX_CORRECTION,
    TEST_ALPHA,
)
from paper.claims.verdicts_bounds import NEAR_TOL, trend_weights
from paper.settings import PAPER_TABLE1
from reports.stats import ALPHA, contrast_t, curve_shape, quantile_curve, simultaneous_band, zero_events_bound

SIMS = 5000  # MC s.e. of a 5% rate: 0.0031; of any rate up to 14%: <= 0.005
RUN = Path(__file__).resolve().parents[2] / "reproduction" / "paper"
SOURCES = ("resampled", "normal")
FAMILY = "above_baselines"  # the family of the run's own methods' claims (paper.claims.method_claims)


# ------------------------------------------------------------ vectorized tests
def welch(groups: Sequence[np.ndarray], weights: Sequence[float], null: float = 0.0
          ) -> tuple[np.ndarray, np.ndarray]:
    """(p_greater, p_less), each (M,), of sum_k w_k mean_k vs ``null`` for ``groups`` (M, S_k)
    (or (M, S_k, G): then (M, G)): ``reports.stats.contrast_t`` over the simulations, the
    test ``reports.stats.t_test`` runs on one."""
    t = contrast_t(groups, weights, null, axis=1)
    return t.p_greater, t.p_less


def decide(pg: np.ndarray, pl: np.ndarray, contra: float) -> np.ndarray:
    """``paper.claims.verdicts.decide`` per simulation (support at ``TEST_ALPHA``)."""
    return np.where(pg < TEST_ALPHA, 1, np.where(pl < contra, -1, 0))


def v_greater(g: Sequence[np.ndarray], contra: float) -> np.ndarray:
    return decide(*welch(g, [1.0, -1.0]), contra)


def v_gap(g: Sequence[np.ndarray], contra: float) -> np.ndarray:
    return decide(*welch(g, [1.0, -1.0, -1.0, 1.0]), contra)


def make_below(bound: float) -> Callable[[Sequence[np.ndarray], float], np.ndarray]:
    """``check_below`` / ``check_corrections`` against ``bound``."""
    def v(g: Sequence[np.ndarray], contra: float) -> np.ndarray:
        pg, pl = welch([-g[0]], [1.0], -bound)
        return decide(pg, pl, contra)
    return v


def make_near(target: float, tol: float = NEAR_TOL) -> Callable[[Sequence[np.ndarray], float], np.ndarray]:
    """``check_near``: two one-sided tests, each side contradicting at contra / 2."""
    def v(g: Sequence[np.ndarray], contra: float) -> np.ndarray:
        a_pg, a_pl = welch(g, [1.0], target * (1 - tol))
        b_pg, b_pl = welch(g, [1.0], target * (1 + tol))
        bad = (a_pl < contra / 2) | (b_pg < contra / 2)
        return np.where(bad, -1, np.where((a_pg < TEST_ALPHA) & (b_pl < TEST_ALPHA), 1, 0))
    return v


def make_trend(ns: Sequence[int]) -> Callable[[Sequence[np.ndarray], float], np.ndarray]:
    w = list(trend_weights(ns))

    def v(g: Sequence[np.ndarray], contra: float) -> np.ndarray:
        return decide(*welch(g, w), contra)
    return v


def band_bounds(h: np.ndarray, i: np.ndarray, alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """``reports.stats.simultaneous_band`` per simulation: (lower, upper), each (M, G),
    for per-seed curves ``h`` (M, S_h, G), ``i`` (M, S_i, G)."""
    _, lo, hi = simultaneous_band(h, i, alpha, axis=1)
    return lo, hi


def v_curves(g: Sequence[np.ndarray], contra: float) -> np.ndarray:
    """``check_curves`` on per-seed [mean, quantiles at BAND_PCT] vectors (M, S, 1 + G)."""
    h, i = g
    pg, pl = welch([h[:, :, 0], i[:, :, 0]], [1.0, -1.0])
    lo, _ = band_bounds(h[:, :, 1:], i[:, :, 1:], TEST_ALPHA)
    _, hi_c = band_bounds(h[:, :, 1:], i[:, :, 1:], contra / 2)
    bad = (pl < contra / 2) | (hi_c < -BAND_TOL).any(axis=1)
    return np.where(bad, -1, np.where((pg < TEST_ALPHA) & (lo > -BAND_TOL).all(axis=1), 1, 0))


def v_convergence(g: Sequence[np.ndarray], contra: float) -> np.ndarray:
    """``check_convergence`` on per-seed (gain, drift) pairs (M, S, 2)."""
    gain, drift = g[0][:, :, 0], g[0][:, :, 1]
    g_pg, g_pl = welch([gain], [1.0])
    a_pg, a_pl = welch([drift - CONV_REL_TOL * gain], [1.0])
    b_pg, b_pl = welch([drift + CONV_REL_TOL * gain], [1.0])
    c = contra / 3
    bad = (g_pl < c) | (a_pg < c) | (b_pl < c)
    return np.where(bad, -1, np.where((g_pg < TEST_ALPHA) & (a_pl < TEST_ALPHA) & (b_pg < TEST_ALPHA), 1, 0))


def _contrast(g: Sequence[np.ndarray], w: Sequence[float]) -> np.ndarray:
    return sum(wk * gk.mean(axis=1) for wk, gk in zip(w, g, strict=True))


def point_contrast(w: Sequence[float]) -> Callable[[Sequence[np.ndarray]], np.ndarray]:
    """Per simulation, whether the contrast estimate points toward the claim (> 0)."""
    return lambda g: _contrast(g, w) > 0


def point_curves(g: Sequence[np.ndarray]) -> np.ndarray:
    return g[0][:, :, 0].mean(axis=1) - g[1][:, :, 0].mean(axis=1) > 0


def point_region(low: float, high: float) -> Callable[[Sequence[np.ndarray]], np.ndarray]:
    """The mean inside the claim's region (``paper.claims.sides``)."""
    def p(g: Sequence[np.ndarray]) -> np.ndarray:
        m = g[0].mean(axis=1)
        return (low < m) & (m < high)
    return p


def point_convergence(g: Sequence[np.ndarray]) -> np.ndarray:
    gain, drift = g[0][:, :, 0].mean(axis=1), g[0][:, :, 1].mean(axis=1)
    return (gain > 0) & (np.abs(drift) < CONV_REL_TOL * gain)


def sign_codes(points: np.ndarray) -> np.ndarray:
    """``paper.claims.pooled.sign_test`` per simulation of (k, M) directions (True: toward)."""
    k = points.shape[0]
    toward = points.sum(axis=0)
    p_toward = sps.binom.sf(toward - 1, k, 0.5)
    p_against = sps.binom.cdf(toward, k, 0.5)
    return np.where(p_toward < TEST_ALPHA, 1, np.where(p_against < TEST_ALPHA, -1, 0))


def combine_codes(v: np.ndarray) -> np.ndarray:
    """``paper.claims.verdicts.combine`` of (k, M) check codes: any contradicted -> -1, all
    supported -> 1, else 0."""
    return np.where((v == -1).any(axis=0), -1, np.where((v == 1).all(axis=0), 1, 0))


# ----------------------------------------------------------- checks from data
@dataclass(frozen=True)
class Spec:
    """One check as the calibration sees it: per-group observed spread (``sd``: (K,) or
    (K, D) for vector statistics), seed counts, the boundary and effect means (K[, D]),
    the claim's pooled standardized residuals ``z`` (R[, D]) and its verdict function."""

    claim: str
    check: str
    counts: tuple[int, ...]
    sd: np.ndarray
    null: np.ndarray
    effect: np.ndarray
    verdict: Callable[[Sequence[np.ndarray], float], np.ndarray]
    z: np.ndarray = field(default_factory=lambda: np.zeros((0,)))
    point: Callable[[Sequence[np.ndarray]], np.ndarray] | None = None  # direction of the estimate

    def draw(self, rng: np.random.Generator, sims: int, truth: str, source: str) -> list[np.ndarray]:
        mu = self.null if truth == "null" else self.effect
        out = []
        for k, s in enumerate(self.counts):
            shape = (sims, s) + self.sd.shape[1:]
            if source == "normal" or len(self.z) == 0:
                z = rng.standard_normal(shape)
            else:  # smoothed bootstrap: a pooled residual plus kernel noise, unit variance kept
                h = 1.06 * len(self.z) ** -0.2  # Silverman's bandwidth for a unit-variance sample
                z = ((self.z[rng.integers(len(self.z), size=(sims, s))] + h * rng.standard_normal(shape))
                     / np.sqrt(1 + h * h))
            out.append(mu[k] + self.sd[k] * z)
        return out


def _std_resid(groups: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Each group's per-seed values (S[, D]) centred and divided by its own sd (0 where it has none)."""
    out = []
    for g in groups:
        sd = g.std(axis=0, ddof=1)
        out.append(np.where(sd > 0, (g - g.mean(axis=0)) / np.where(sd > 0, sd, 1.0), 0.0))
    return out


def _pooled(specs: list[tuple[str, list[np.ndarray]]]) -> np.ndarray:
    """The claim's standardized residuals pooled and scaled to unit variance per column."""
    z = np.concatenate([r for _, gs in specs for r in _std_resid(gs)])
    s = z.std(axis=0)
    return z / np.where(s > 0, s, 1.0)


_POINTS: dict[Callable, Callable | None] = {}  # verdict function -> its direction function (``add`` records them)


def _spec(claim: str, check: str, gs: list[np.ndarray], null: list, effect: list,
          verdict: Callable) -> Spec:
    return Spec(claim, check, tuple(len(g) for g in gs), np.array([g.std(axis=0, ddof=1) for g in gs]),
                np.array(null, dtype=np.float64), np.array(effect, dtype=np.float64), verdict,
                point=_POINTS.get(verdict))


def _finite(x: np.ndarray) -> np.ndarray:
    return x[np.isfinite(x).all(axis=tuple(range(1, x.ndim)))] if x.ndim > 1 else x[np.isfinite(x)]


def observed_specs(train: pd.DataFrame, evals: pd.DataFrame) -> dict[str, list[Spec]]:
    """Per claim key, one ``Spec`` per check the committed claims page has with data
    (>= 3 seeds per side), in the claims' order."""
    ev = C.with_execution(evals)
    out: dict[str, list[tuple[str, list[np.ndarray], list, list, Callable]]] = {}

    def add(key: str, label: str, gs: list[np.ndarray], null: list, effect: list, v: Callable,
            point: Callable | None = None) -> None:
        gs = [_finite(np.asarray(g, dtype=np.float64)) for g in gs]
        if min(len(g) for g in gs) >= 3:
            _POINTS[v] = point
            out.setdefault(key, []).append((label, gs, null, effect, v))

    for n, p in C.PAPER["fig1a"]:
        a, b = (C.final_means(C.select(train, m, n, p)) for m in ("hierarchical", "decentralized"))
        mid, eff = float(np.mean([a.mean(), b.mean()])), REWARD_FRAC * abs(b.mean())
        add("hier_above_dec", C._cfg(n, p), [a, b], [mid, mid], [mid + eff, mid], v_greater,
            point_contrast([1.0, -1.0]))
    for large, small, p in C.PAPER["gap"]:
        gs = [C.final_means(C.select(train, m, n, p)) for n in (large, small) for m in ("hierarchical",
            "decentralized")]
        m = [float(g.mean()) for g in gs]
        base = m[1] + m[2] - m[3]  # gap(large) = gap(small)
        add("gap_widens", f"Gap({large}) vs Gap({small})", gs, [base, *m[1:]],
            [base + REWARD_FRAC * abs(m[1]), *m[1:]], v_gap, point_contrast([1.0, -1.0, -1.0, 1.0]))
    for n, p in C.PAPER["fig1b"]:
        shapes = [curve_shape(c, FINAL_FRAC) for c in C.per_cell(C.select(train, "hierarchical", n, p), "team_return")]
        if shapes and all(s is not None for s in shapes):
            gd = np.array([[s.gain, s.drift] for s in shapes if s is not None])
            gain = abs(float(gd[:, 0].mean()))
            add("convergence", C._cfg(n, p), [gd], [[gain, CONV_REL_TOL * gain]], [[gain, 0.0]], v_convergence,
                point_convergence)
    for n, p in C.PAPER["fig2"]:
        h, i = C.select(ev, "hierarchical", n, p), C.select(ev, "ic3net", n, p)
        for mode, hh, ii in (C.mode_pairs(h, i) if len(h) and len(i) else []):
            vecs = [np.array([[x.mean(), *quantile_curve(x, BAND_PCT)] for x in C.per_cell(r, "success_rate")])
                    for r in (hh, ii)]
            base = vecs[1].mean(axis=0)
            add("above_ic3net", f"{C._cfg(n, p)} {mode}", vecs, [base, base], [base + EFFECT_SUCCESS, base], v_curves,
                point_curves)
    BELOW = {b: make_below(b) for b in (PRINT_BOUND, MAX_CORRECTION, FALLBACK_BOUND)}  # noqa: N806
    for n, p in C.PAPER["table1"]:
        for mode, rows in C._hier_modes(ev, n, p):
            label = f"{C._cfg(n, p)} {mode}"
            cr = C.seed_means(rows, "collision_rate")
            add("collisions_printed", label, [cr], [PRINT_BOUND], [0.0], BELOW[PRINT_BOUND],
                point_region(-np.inf, PRINT_BOUND))
            co = C.seed_means(rows, "correction_rate")
            add("few_corrections", label, [co], [MAX_CORRECTION], [PAPER_TABLE1[n][1]], BELOW[MAX_CORRECTION],
                point_region(-np.inf, MAX_CORRECTION))
            mc, target = C.seed_means(rows, "mean_candidates"), PAPER_TABLE1[n][2]
            add("table1_candidates", label, [mc], [target * (1 + NEAR_TOL)], [target], make_near(target),
                None)  # a two-sided band: no sign test (paper.claims.pooled)
            fb = C.seed_means(rows, "fallback_rate")
            add("normal_search", label, [fb], [FALLBACK_BOUND], [FALLBACK_BOUND / 2], BELOW[FALLBACK_BOUND],
                point_region(-np.inf, FALLBACK_BOUND))
    ns = [n for n, _ in C.PAPER["table1"]]
    per_n = [dict(C._hier_modes(ev, n, 0.2)) for n in ns]
    for mode in C.MODE_ORDER:
        if all(mode in d for d in per_n):
            gs = [C.seed_means(d[mode], "mean_candidates") for d in per_n]
            flat = [float(np.mean([g.mean() for g in gs]))] * len(gs)
            slope = [flat[0] + PAPER_SLOPE * (n - np.mean(ns)) for n in ns]
            add("searches_grow", f"N = 40..100 {mode}", gs, flat, slope, make_trend(ns),
                point_contrast(list(trend_weights(ns))))
    # "M above each baseline" (paper.claims.method_claims): the reproduction holds no method of
    # a user's, so the paper's method stands in for M, with its own spread, seeds and modes.
    baselines, _ = MC.methods_by_role(ev)
    for ref in sorted(m for m in set(map(str, ev["method"])) if MC.paper_role(m) == REFERENCE):
        for bname, n_b, p_b, m_mode, mm, bb in MC.paired_rows(ev, ref, baselines):
            gs = [C.seed_means(mm, "success_rate"), C.seed_means(bb, "success_rate")]
            mid = float(np.mean([g[np.isfinite(g)].mean() for g in gs]))
            add(FAMILY, f"vs {bname} {C._cfg(n_b, p_b)} {m_mode}", gs, [mid, mid],
                [mid + EFFECT_SUCCESS, mid], v_greater, point_contrast([1.0, -1.0]))
    specs: dict[str, list[Spec]] = {}
    for key, rows in out.items():
        z = _pooled([(r[0], r[1]) for r in rows])
        specs[key] = [replace(_spec(key, label, gs, null, eff, v), z=z) for label, gs, null, eff, v in rows]
    return specs


# ------------------------------------------------------------------ the table
def null_limit(sims: int, alpha: float = ALPHA) -> float:
    """Largest acceptable error rate: alpha + 2 Monte-Carlo standard errors at alpha."""
    return alpha + 2.0 * float(np.sqrt(alpha * (1 - alpha) / sims))


def _row(claim: str, check: str, seeds: str, source: str, truth: str, k: int, sims: int,
         v: np.ndarray, boundary: bool = True) -> dict:
    sup, con = float(np.mean(v == 1)), float(np.mean(v == -1))
    lim = null_limit(sims)
    return {"test": claim, "check": check, "truth": truth, "source": source, "seeds": seeds, "k": k,
            "sims": sims, "rate": sup, "mc_se": float(np.sqrt(sup * (1 - sup) / sims)),
            "null_ok": bool(truth == "effect" or sup <= lim), "contradicted": con,
            "contra_se": float(np.sqrt(con * (1 - con) / sims)),
            "contra_ok": bool(not (truth == "effect" or boundary) or con <= lim)}


def _rng(seed: int, *key: object) -> np.random.Generator:
    words = [int.from_bytes(str(x).encode()[:8].ljust(8, b"\0"), "little") % 2**32 for x in key]
    return np.random.default_rng(np.random.SeedSequence([seed, *words, len(str(key))]))


def calibrate_specs(specs: dict[str, list[Spec]], sims: int = SIMS, seed: int = 0,
                    sources: Sequence[str] = SOURCES) -> pd.DataFrame:
    """Rows per check (null and effect, per source) at the claim's level 0.05 / k, and per
    claim ("family"): support under its least favourable null (the first check at its
    boundary, the others at the effect: the intersection's worst case) and contradiction
    with every check at its boundary (the union's worst case)."""
    rows = []
    for key, checks in specs.items():
        k = len(checks)
        contra = TEST_ALPHA / k
        for source in sources:
            fam: dict[str, list[np.ndarray]] = {"null": [], "effect": [], "one": []}
            for j, sp in enumerate(checks):
                seeds = " vs ".join(map(str, sp.counts))
                for truth in ("null", "effect"):
                    v = sp.verdict(sp.draw(_rng(seed, key, j, source, truth), sims, truth, source), contra)
                    rows.append(_row(key, sp.check, seeds, source, truth, k, sims, v))
                    fam[truth].append(v)
                fam["one"].append(fam["null"][-1] if j == 0 else fam["effect"][-1])
            if k > 1 and all(sp.point is not None for sp in checks):
                for label, truth in ((f"pooled sign test ({k} checks): every check at its boundary", "null"),
                                     (f"pooled sign test ({k} checks): every check at the effect", "effect")):
                    pts = np.stack([sp.point(sp.draw(_rng(seed, key, j, source, truth), sims, truth, source))
                                    for j, sp in enumerate(checks) if sp.point is not None])
                    rows.append(_row(key, label, "as each", source, truth, k, sims, sign_codes(pts)))
            if k > 1:
                for label, truth, vs in (
                        (f"whole claim ({k} checks): the first at its boundary, the rest at the effect",
                         "null", fam["one"]),
                        (f"whole claim ({k} checks): every check at its boundary", "null", fam["null"]),
                        (f"whole claim ({k} checks): every check at the effect", "effect", fam["effect"])):
                    rows.append(_row(key, label, "as each", source, truth, k, sims, combine_codes(np.stack(vs))))
    return pd.DataFrame(rows)


def collision_rows(seed: int = 0, sims: int = SIMS, episodes: Sequence[int] = (300,)) -> pd.DataFrame:
    """``no_collisions`` (a literal zero over every episode): stated parametric case. Null:
    each episode collides with probability 1 - 0.05^(1/n) (the exact bound); effect: never."""
    rows = []
    for n in episodes:
        rng = _rng(seed, "no_collisions", n)
        q = zero_events_bound(n)
        hits = rng.binomial(n, q, size=sims)
        v = np.where(hits == 0, 1, -1)
        rows.append(_row("no_collisions", f"{n} episodes", "3", "binomial", "null", 1, sims, v, boundary=False))
        rows.append(_row("no_collisions", f"{n} episodes", "3", "binomial", "effect", 1, sims,
                         np.ones(sims, dtype=int)))
    return pd.DataFrame(rows)


def calibrate_run(run: Path | str = RUN, sims: int = SIMS, seed: int = 0) -> pd.DataFrame:
    """The whole table for the store under ``run`` (default the committed reproduction)."""
    from reports.data.store import load_store
    from reports.data.variants import cell_variants, default_rows

    store = load_store(run)
    variants = cell_variants(store.cells)
    specs = observed_specs(default_rows(store.train, variants), default_rows(store.eval, variants))
    return pd.concat([calibrate_specs(specs, sims, seed), collision_rows(seed, sims)], ignore_index=True)
