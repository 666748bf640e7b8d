"""``bench calibrate``: how often each claim test says *supported* when the claim is
false (must be <= 5% + Monte-Carlo error) and when it is true with a stated effect (power),
and how often it says *contradicted* when the claim holds or sits at its boundary (must be
<= 5% + Monte-Carlo error too). Whole claims over several configurations and execution
modes are simulated as well ("families"): one contradicted check contradicts a claim, so
there the checks' Bonferroni level (``paper.claims.verdicts``) is what keeps the rate down.

Simulated per-seed data with known truth is laid out as training / evaluation tables
(the store's columns) and pushed through the claims' own functions
(``paper.claims.claims.claim_*``), so the numbers describe exactly what the claims page runs.
Episode noise within a training curve is AR(1) (phi = 0.8): a test that treated episodes
as independent would show it. Also measures the coverage of the 95% intervals the
reports print (``reports.stats.rate_ci``, ``positive_ci``) at the run's own spread. Every
stream is seeded: the same ``seed`` gives the same table.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from paper.claims import claim_power
from paper.claims import claims as C
from paper.claims import verdicts as V
from paper.claims.method_claims import claim_above_baselines
from reports.stats import coverage, zero_events_bound

SEED_COUNTS = (3, 5, 10)
ALPHA = 0.05
TRAIN_EPISODES = 200  # windows of 40 episodes
EVAL_EPISODES = 20
PHI = 0.8  # AR(1) coefficient of episode noise in training curves


def _ar1(rng: np.random.Generator, shape: tuple[int, int], sd: float = 1.0) -> np.ndarray:
    """(S, T) AR(1) noise with stationary s.d. ``sd``."""
    e = rng.normal(0.0, sd * np.sqrt(1 - PHI**2), shape)
    out = np.empty(shape)
    out[:, 0] = rng.normal(0.0, sd, shape[0])
    for t in range(1, shape[1]):
        out[:, t] = PHI * out[:, t - 1] + e[:, t]
    return out


def _train(method: str, n: int, curves: np.ndarray, first_cell: int = 0) -> pd.DataFrame:
    """Training rows (cell_id, episode, team_return, method, n_robots, loss_p) of (S, T) curves."""
    s, t = curves.shape
    return pd.DataFrame({"cell_id": np.repeat([f"{method}{n}-{first_cell + k}" for k in range(s)], t),
                         "episode": np.tile(np.arange(t), s), "team_return": curves.reshape(-1),
                         "method": method, "n_robots": n, "loss_p": 0.2})


def _eval(method: str, n: int, cols: dict[str, np.ndarray], p: float = 0.2,
          execution: str = "argmax") -> pd.DataFrame:
    """Evaluation rows of (S, E) metric arrays, one execution mode, safety filter on."""
    s, e = next(iter(cols.values())).shape
    return pd.DataFrame({"cell_id": np.repeat([f"{method}{n}-{p:g}-{k}" for k in range(s)], e),
                         "episode": np.tile(np.arange(e), s),
                         **{k: v.reshape(-1) for k, v in cols.items()},
                         "method": method, "n_robots": n, "loss_p": p,
                         "safety_filter": method == "hierarchical", "execution": execution})


def _plateau(rng: np.random.Generator, levels: np.ndarray) -> np.ndarray:
    """(S, T) curves rising from 0 to per-seed ``levels`` (S,) with AR(1) noise."""
    e = np.arange(TRAIN_EPISODES)
    return levels[:, None] * (1 - np.exp(-e / 15.0))[None, :] + _ar1(rng, (len(levels), TRAIN_EPISODES))


# ---------------------------------------------------------------- scenarios
def sim_hier_above_dec(rng: np.random.Generator, s: int, effect: bool) -> str:
    """Final rewards: hier seed levels N(10 + 3 effect, 1), dec N(10, 1.5)."""
    h = _plateau(rng, 10.0 + 3.0 * effect + rng.normal(0, 1.0, s))
    d = _plateau(rng, 10.0 + rng.normal(0, 1.5, s))
    train = pd.concat([_train("hierarchical", 20, h), _train("decentralized", 20, d)])
    return C.claim_hier_above_dec(train, configs=[(20, 0.2)]).checks[0].verdict


def sim_gap_widens(rng: np.random.Generator, s: int, effect: bool) -> str:
    """Gap 2 at N = 20; at 60, gap 2 (+3 effect); seed s.d. 1."""
    parts = [_train("hierarchical", 60, _plateau(rng, 10.0 + rng.normal(0, 1, s))),
             _train("decentralized", 60, _plateau(rng, 8.0 - 3.0 * effect + rng.normal(0, 1, s))),
             _train("hierarchical", 20, _plateau(rng, 10.0 + rng.normal(0, 1, s))),
             _train("decentralized", 20, _plateau(rng, 8.0 + rng.normal(0, 1, s)))]
    return C.claim_gap_widens(pd.concat(parts), configs=[(60, 20, 0.2)]).checks[0].verdict


def _ramp_curves(rng: np.random.Generator, s: int, drift_frac: float, gain: float = 5.0) -> np.ndarray:
    """(S, T): flat 0 over the first 20%, a ramp, then a last 20% window of mean G_s
    (G_s ~ N(gain, 1)) drifting by exactly drift_frac x G_s across it; AR(1) noise s.d. 1."""
    t, w = TRAIN_EPISODES, int(V.FINAL_FRAC * TRAIN_EPISODES)
    g = gain + rng.normal(0, 1.0, s)
    x = np.arange(w) - (w - 1) / 2.0
    last = g[:, None] + (drift_frac * g / w)[:, None] * x[None, :]
    ramp = np.linspace(0.0, 1.0, t - 2 * w + 2)[1:-1][None, :] * last[:, :1]
    return np.concatenate([np.zeros((s, w)), ramp, last], axis=1) + _ar1(rng, (s, t))


def sim_convergence_at_tolerance(rng: np.random.Generator, s: int, effect: bool) -> str:
    """Null: still rising by exactly the tolerance (20% of the gain) over the last window.
    Effect: flat last window."""
    c = _ramp_curves(rng, s, 0.0 if effect else V.CONV_REL_TOL)
    return C.claim_convergence(_train("hierarchical", 80, c), configs=[(80, 0.2)]).checks[0].verdict


def sim_convergence_flat(rng: np.random.Generator, s: int, effect: bool) -> str:
    """Null: no gain at all (flat curve). Effect: gain 5, flat last window."""
    c = _ramp_curves(rng, s, 0.0) if effect else _ar1(rng, (s, TRAIN_EPISODES)) + rng.normal(0, 1, (s, 1))
    return C.claim_convergence(_train("hierarchical", 80, c), configs=[(80, 0.2)]).checks[0].verdict


def _success(rng: np.random.Generator, s: int, mean: float) -> np.ndarray:
    """(S, E) success rates: seed level N(mean, 0.05), episodes +- N(0, 0.15)."""
    return mean + rng.normal(0, 0.05, (s, 1)) + rng.normal(0, 0.15, (s, EVAL_EPISODES))


def sim_above_ic3net(rng: np.random.Generator, s: int, effect: bool) -> str:
    """Identical methods (null) or hierarchical + 0.2 at every episode (effect)."""
    ev = pd.concat([_eval("hierarchical", 40, {"success_rate": _success(rng, s, 0.6 + 0.2 * effect)}),
                    _eval("ic3net", 40, {"success_rate": _success(rng, s, 0.6)})])
    return C.claim_above_ic3net(ev, configs=[(40, 0.2)]).checks[0].verdict


def sim_above_ic3net_band(rng: np.random.Generator, s: int, effect: bool) -> str:
    """Null: hierarchical higher by 0.3 on its best 70% of episodes but exactly BAND_TOL
    lower on its worst 30% (percentiles 10, 20 at the tolerance). Effect: no lower part."""
    q = np.sort(rng.normal(0, 0.2, EVAL_EPISODES))
    k = np.arange(EVAL_EPISODES)
    shift = np.where(k < int(0.3 * EVAL_EPISODES), 0.3 if effect else -V.BAND_TOL, 0.3)
    ic3 = 0.5 + q[None, :] + rng.normal(0, 0.05, (s, 1))
    hier = 0.5 + (q + shift)[None, :] + rng.normal(0, 0.05, (s, 1))
    ev = pd.concat([_eval("hierarchical", 40, {"success_rate": hier}),
                    _eval("ic3net", 40, {"success_rate": ic3})])
    return C.claim_above_ic3net(ev, configs=[(40, 0.2)]).checks[0].verdict


def sim_no_collisions(rng: np.random.Generator, s: int, effect: bool) -> str:
    """Null: each episode collides with probability 1 - 0.05^(1/n) (the boundary of the
    exact bound, n = all episodes). Effect: no collisions."""
    q = 0.0 if effect else zero_events_bound(s * EVAL_EPISODES)
    coll = (rng.random((s, EVAL_EPISODES)) < q) * 0.01
    return C.claim_no_collisions(_eval("hierarchical", 40, {"collision_rate": coll}),
                                 configs=[(40, 0.2)]).checks[0].verdict


def sim_few_corrections(rng: np.random.Generator, s: int, effect: bool) -> str:
    """Seed mean correction rate N(8%, 1%) (null) or N(5%, 1%); episodes +- N(0, 1%)."""
    m = (0.05 if effect else V.MAX_CORRECTION) + rng.normal(0, 0.01, (s, 1))
    corr = m + rng.normal(0, 0.01, (s, EVAL_EPISODES))
    return C.claim_few_corrections(_eval("hierarchical", 40, {"correction_rate": corr}),
                                   configs=[(40, 0.2)]).checks[0].verdict


# ----------------------------------------------------------------- families
FAMILY_MODES = ("argmax", "sample", "sample@0.5")


def sim_family_hier_above_dec(rng: np.random.Generator, s: int, effect: bool) -> str:
    """Fig. 1(a)'s claim as a whole: N = 20, 40, 60, each as ``sim_hier_above_dec``."""
    parts = []
    for n in (20, 40, 60):
        parts += [_train("hierarchical", n, _plateau(rng, 10.0 + 3.0 * effect + rng.normal(0, 1.0, s))),
                  _train("decentralized", n, _plateau(rng, 10.0 + rng.normal(0, 1.5, s)))]
    return C.claim_hier_above_dec(pd.concat(parts), configs=[(20, 0.2), (40, 0.2), (60, 0.2)]).verdict


def sim_family_above_ic3net(rng: np.random.Generator, s: int, effect: bool) -> str:
    """Fig. 2's claim as a whole: 6 configurations x 3 execution modes (18 checks), each
    as ``sim_above_ic3net`` with its own draws."""
    configs = [(n, p) for n in (40, 60) for p in (0.2, 0.4, 0.6)]
    ev = pd.concat([_eval(m, n, {"success_rate": _success(rng, s, 0.6 + 0.2 * effect * (m == "hierarchical"))},
                          p, mode)
                    for n, p in configs for mode in FAMILY_MODES for m in ("hierarchical", "ic3net")])
    return C.claim_above_ic3net(ev, configs=configs).verdict


def sim_family_few_corrections(rng: np.random.Generator, s: int, effect: bool) -> str:
    """Table I's correction claim as a whole: 5 configurations x 3 modes (15 checks)."""
    configs = [(n, 0.2) for n in (40, 60, 80, 90, 100)]
    parts = []
    for n, p in configs:
        for mode in FAMILY_MODES:
            m = (0.05 if effect else V.MAX_CORRECTION) + rng.normal(0, 0.01, (s, 1))
            parts.append(_eval("hierarchical", n, {"correction_rate": m + rng.normal(0, 0.01, (s, EVAL_EPISODES))},
                               p, mode))
    return C.claim_few_corrections(pd.concat(parts), configs=configs).verdict


def sim_family_above_baselines(rng: np.random.Generator, s: int, effect: bool) -> str:
    """A run's own method (``mine``, a name no package registers) above each baseline, as
    the claims page judges it (paper.claims.method_claims): against decentralized in two
    modes and against PIBT's planner from each (4 checks); +0.2 success (effect)."""
    parts = [_eval("decentralized", 20, {"success_rate": _success(rng, s, 0.6)}, 0.2, mode)
             for mode in FAMILY_MODES[:2]]
    parts.append(_eval("pibt", 20, {"success_rate": _success(rng, s, 0.6)}, 0.2, "planner"))
    parts += [_eval("mine", 20, {"success_rate": _success(rng, s, 0.6 + 0.2 * effect)}, 0.2, mode)
              for mode in FAMILY_MODES[:2]]
    return claim_above_baselines(pd.concat(parts), "mine", ["decentralized", "pibt"]).verdict


@dataclass(frozen=True)
class Scenario:
    test: str  # claim key
    name: str
    effect: str  # what the "effect" simulation makes true
    sim: Callable[[np.random.Generator, int, bool], str]
    boundary: bool = True  # the null sits on the claim's boundary: a contradiction there is false too


SCENARIOS = (
    Scenario("hier_above_dec", "equal final rewards (seed s.d. 1 vs 1.5)", "+3 final reward", sim_hier_above_dec),
    Scenario("gap_widens", "equal gaps", "gap at 60 larger by 3 (seed s.d. 1)", sim_gap_widens),
    Scenario("convergence", "still rising by exactly the tolerance", "flat after the ramp",
             sim_convergence_at_tolerance),
    Scenario("convergence", "no gain (flat curve)", "gain 5, flat after the ramp", sim_convergence_flat,
             boundary=False),
    Scenario("above_ic3net", "identical methods", "+0.2 success at every episode", sim_above_ic3net),
    Scenario("above_ic3net", "worst 30% of episodes exactly 0.05 lower", "+0.3 everywhere",
             sim_above_ic3net_band),
    Scenario("no_collisions", "per-episode collision probability at the 95% bound", "no collisions",
             sim_no_collisions, boundary=False),
    Scenario("few_corrections", "mean correction rate exactly 8%", "mean correction rate 5%",
             sim_few_corrections),
    Scenario("hier_above_dec", "family of 3 configurations, equal final rewards", "+3 at each",
             sim_family_hier_above_dec),
    Scenario("above_ic3net", "family of 6 configurations x 3 modes, identical methods",
             "+0.2 at each", sim_family_above_ic3net),
    Scenario("few_corrections", "family of 5 configurations x 3 modes, exactly 8%", "5% at each",
             sim_family_few_corrections),
    Scenario("above_baselines", "family of 2 baselines x 2 modes, identical success", "+0.2 at each",
             sim_family_above_baselines),
)


FAMILIES = tuple(i for i, sc in enumerate(SCENARIOS) if sc.name.startswith("family"))


def null_limit(sims: int, alpha: float = ALPHA) -> float:
    """Largest acceptable null rate: alpha + 2 Monte-Carlo standard errors at alpha."""
    return alpha + 2.0 * float(np.sqrt(alpha * (1 - alpha) / sims))


def calibrate(sims: int = 1000, seed: int = 0, seed_counts: tuple[int, ...] = SEED_COUNTS,
              scenarios: Sequence[int] | None = None) -> pd.DataFrame:
    """One row per (test, scenario, truth in {null, effect}, seeds): the rate of
    ``supported`` over ``sims`` simulations, its MC standard error, (null rows) whether it
    is within ``null_limit``; the rate of ``contradicted`` and whether it is within the
    limit where the claim holds (effect rows) or sits at its boundary (boundary nulls).
    ``scenarios``: indices into ``SCENARIOS`` to run (default all); each keeps its own
    random streams, so a subset gives the same rows as the whole."""
    rows = []
    for i, sc in enumerate(SCENARIOS):
        if scenarios is not None and i not in scenarios:
            continue
        for s in seed_counts:
            for effect in (False, True):
                rng = np.random.default_rng(np.random.SeedSequence([seed, i, s, int(effect)]))
                with claim_power.skipped():  # verdicts only: power is the page's, not the simulation's
                    verdicts = [sc.sim(rng, s, effect) for _ in range(sims)]
                rate = verdicts.count(V.SUPPORTED) / sims
                contra = verdicts.count(V.CONTRADICTED) / sims
                rows.append({"test": sc.test, "truth": "effect" if effect else "null",
                             "scenario": sc.effect if effect else sc.name, "seeds": s, "sims": sims,
                             "rate": rate, "mc_se": float(np.sqrt(rate * (1 - rate) / sims)),
                             "null_ok": bool(effect or rate <= null_limit(sims)),
                             "contradicted": contra,
                             "contra_ok": bool(not (effect or sc.boundary) or contra <= null_limit(sims))})
    return pd.DataFrame(rows)


def ci_coverage(sims: int = 2000, seed: int = 0, run: Path | str | None = None) -> pd.DataFrame:
    """Coverage of the true mean by the 95% intervals the reports print, at the spread of
    the store under ``run`` (default the committed reproduction): per metric (success rate:
    ``rate_ci``; mean candidates and throughput: ``positive_ci``) and seed count, the
    lowest, median and share >= 93% of the simulated coverages over the run's groups
    (method, N, p, mode), each at its own mean, s.d. and seeds (``reports.stats.coverage``)."""
    from paper.claims.calibrate_data import RUN
    from reports.data.store import load_store

    ev = C.with_execution(load_store(run if run is not None else RUN).eval)
    rows = []
    for metric, kind, name in (("success_rate", "rate", "rate_ci (logit t over seeds)"),
                               ("mean_candidates", "positive", "positive_ci (Cox, over seeds)"),
                               ("throughput", "positive", "positive_ci (Cox, over seeds)")):
        if metric not in ev.columns:
            continue
        per = ev.groupby(["method", "n_robots", "loss_p", "execution", "cell_id"])[metric].mean().dropna()
        if per.empty:
            continue
        stats = per.groupby(level=[0, 1, 2, 3]).agg(["mean", "std", "count"])
        stats = stats[stats["count"] >= 2]
        for s_count, g in stats.groupby("count"):
            cov = np.array([coverage(kind, r["mean"], r["std"], int(s_count), sims, seed=seed)
                            for _, r in g.iterrows()])
            cov = cov[np.isfinite(cov)]
            if cov.size:
                rows.append({"interval": name, "metric": metric, "seeds": int(s_count), "groups": int(cov.size),
                             "lowest": float(cov.min()), "median": float(np.median(cov)),
                             "share_at_least_93": float(np.mean(cov >= 0.93)), "sims": sims})
    return pd.DataFrame(rows)


def calibration_report(sims: int = 5000, seed: int = 0, coverage_sims: int = 2000,
                       run: Path | str | None = None) -> dict:
    """Everything ``bench calibrate --json`` prints: meta, calibration rows (every check
    and whole claim of the store under ``run``, default the committed reproduction, on its
    own spread: ``paper.claims.calibrate_data``), CI coverage rows, and whether every error
    rate is within ``null_limit``. (The synthetic scenarios above, ``calibrate``, push
    tables through the claims' own functions; the fast tests run them.)"""
    from paper.claims.calibrate_data import RUN, SOURCES, calibrate_run

    cal = calibrate_run(run if run is not None else RUN, sims, seed)
    cov = ci_coverage(coverage_sims, seed, run)
    null = cal[cal["truth"] == "null"]
    return {"meta": {"sims": sims, "seed": seed, "alpha": ALPHA, "test_alpha": V.TEST_ALPHA,
                     "null_limit": round(null_limit(sims), 4),
                     "max_mc_se": round(float(max(null["mc_se"].max(), null["contra_se"].max())), 4),
                     "run": "reproduction/paper" if run is None else str(run), "sources": list(SOURCES),
                     "coverage_sims": coverage_sims},
            "all_null_ok": bool(cal["null_ok"].all() and cal["contra_ok"].all()),
            "calibration": cal.to_dict("records"), "coverage": cov.to_dict("records")}
