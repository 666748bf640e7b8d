"""The method-agnostic view of a run: every method it holds, by the name it declares.

Pure functions of the evaluation rows (one row per cell, execution mode and episode, with
the cell's config columns; reports/data/store.py), seed as the unit everywhere:

* ``leaderboard_frame``: per configuration (N, p) and execution mode, each method's
  success rate: the mean over seeds of per-seed means with a 95% CI over seeds inside [0, 1]
  by construction (``reports.stats.rate_ci``, a logit-scale t interval) and its simulated
  coverage at the row's own mean, spread and seeds (``reports.stats.coverage``), and its
  rank within the configuration;
* ``aggregate_frame``: across the configurations every method of the run covers, per
  learned execution mode (a planner's one mode counts in each), the interquartile mean
  of the (seed x configuration) success matrix (rliable's ``aggregate_iqm``), and over
  seeds, the unit, each seed's IQM across the configurations (``reports.stats.iqm``) with
  their mean and ``rate_ci`` and its simulated coverage; and the probability of improvement of
  each ordered pair (rliable's ``probability_of_improvement``, averaged over
  configurations) with its stratified bootstrap CI;
* ``safety_frame``: per method, configuration and mode, the safety columns of Table I for
  every method: collision rate, correction rate, fallback rate and candidates examined
  (NaN where no filter runs), and the payload it measured (scalars per step);
* ``success_figure``: success with its 95% CI against N at each p, or against p at each
  N, one row of panels per execution mode; ``profile_figure``: performance profiles
  (fraction of (seed, configuration) runs with success > tau) with stratified bootstrap bands.

Seeds: aggregates need the same seeds in every configuration (a score matrix), so they
use the seeds every covered configuration of the method has (``common_seeds``) and say
how many; per-configuration rows use every seed.
"""
from __future__ import annotations

from itertools import permutations

import numpy as np
import pandas as pd
from rliable import metrics as rly_metrics

from reports.data.store import execution_order, fmt_p
from reports.figures.plotting import (
    Built,
    fitted_legend,
    label_order,
    method_color,
    method_label,
    method_style,
    new_figure,
    paper_style,
    placeholder,
    ranked_legend,
)
from reports.improvement import poi_coverage, poi_statistic, stratified_band, stratified_ci
from reports.stats import COVERAGE_TARGET, coverage, iqm, positive_ci, rate_ci, trusted, uninformative, untrusted_text
from reports.tables.mapf import SCORE, SCORE_NAME, TASKS, has_lifelong, row_tasks, tasks_of, with_score
from reports.tables.summary import FILTER_NOTE, filter_text, fmt_ci

LEVEL = 0.95
COVERAGE_SIMS = 2000  # simulations behind each printed coverage (MC s.e. <= 0.006 near 93%)
PLANNER = "planner"
SAFETY = ("collision_rate", "correction_rate", "fallback_rate", "mean_candidates", "payload_scalars_per_step")


def _methods(df: pd.DataFrame) -> list[str]:
    return sorted(df["method"].unique(), key=lambda m: (label_order(method_label(m)), m))


def seed_scores(evals: pd.DataFrame, metric: str = "success_rate") -> pd.DataFrame:
    """Per (method, n_robots, loss_p, execution, seed): the mean of ``metric`` over episodes."""
    keys = ["method", "n_robots", "loss_p", "execution", "seed"]
    return evals.groupby(keys, sort=True)[metric].mean().reset_index()


def task_scores(evals: pd.DataFrame) -> pd.DataFrame:
    """Per (task, method, n_robots, loss_p, execution, seed): ``score``, the mean over episodes
    of the task's score (``reports.tables.mapf.with_score``: success of a one-shot cell,
    throughput of a lifelong one), so that a ranking reads one column and never mixes them."""
    keys = ["task", "method", "n_robots", "loss_p", "execution", "seed"]
    return with_score(evals).groupby(keys, sort=True)["score"].mean().reset_index()


def _task_rows(evals: pd.DataFrame, task: str) -> pd.DataFrame:
    """The eval rows of cells of ``task`` (``reports.tables.mapf.row_tasks``)."""
    return evals[row_tasks(evals).eq(task).to_numpy()]


def leaderboard_frame(evals: pd.DataFrame) -> pd.DataFrame:
    """One row per (N, p, execution mode, method): seeds, success mean and 95% CI over
    seeds, and rank (1 = highest mean) among the methods of that configuration and mode
    (a planner's ``planner`` mode ranks with every learned mode). A run with lifelong cells
    (``reports.tables.mapf.row_tasks``) gets a ``task`` column and throughput, its mean and
    95% CI over seeds; a lifelong cell ranks by throughput among the lifelong cells of its
    configuration, a one-shot cell by success among the one-shot ones (docs/decisions/0235)."""
    lifelong = has_lifelong(evals)
    rows = []
    for task in tasks_of(evals):
        part = _task_rows(evals, task)
        scores = seed_scores(part)
        if task == "lifelong":
            scores = scores.merge(seed_scores(part, "throughput"))
        for (n, p, mode, method), g in scores.groupby(["n_robots", "loss_p", "execution", "method"], sort=True):
            x = g["success_rate"].to_numpy()
            mean, lo, hi = rate_ci(x, LEVEL)  # inside [0, 1] by construction (NaN with one seed)
            rows.append({**({"task": task} if lifelong else {}),
                         "n_robots": int(n), "loss_p": float(p), "execution": mode, "method": method,
                         "label": method_label(method), "seeds": len(g), "success": mean,
                         "success_lo": lo, "success_hi": hi,
                         "success_cov": coverage("rate", mean, float(np.std(x, ddof=1)) if len(x) > 1 else np.nan,
                                                 len(x), COVERAGE_SIMS, LEVEL)})
            if task == "lifelong":
                x = g["throughput"].to_numpy()
                mean, lo, hi = positive_ci(x, LEVEL)
                rows[-1].update(throughput=mean, throughput_lo=lo, throughput_hi=hi,
                                throughput_cov=coverage("positive", mean, float(np.std(x, ddof=1)) if len(x) > 1
                                                        else np.nan, len(x), COVERAGE_SIMS, LEVEL))
    out = pd.DataFrame(rows, columns=(["task"] if lifelong else [])
                       + ["n_robots", "loss_p", "execution", "method", "label", "seeds",
                          "success", "success_lo", "success_hi", "success_cov"]
                       + (["throughput", "throughput_lo", "throughput_hi", "throughput_cov"] if lifelong else []))
    out = _with_filter_rates(out, evals)
    if out.empty:
        return out.assign(rank=pd.Series(dtype="int64"))
    out["rank"] = 0
    learned_modes = [m for m in execution_order(out["execution"]) if m != PLANNER] or [PLANNER]
    for key, g in out.groupby((["task"] if lifelong else []) + ["n_robots", "loss_p"]):
        score = "throughput" if lifelong and key[0] == "lifelong" else "success"  # never one against the other
        planners = g[g["execution"] == PLANNER]
        for k, mode in enumerate(learned_modes):
            mine = g[g["execution"] == mode] if mode != PLANNER else g.iloc[:0]
            ranks = pd.concat([mine, planners])[score].rank(ascending=False, method="min").fillna(0)
            for idx in mine.index.tolist() + (planners.index.tolist() if k == 0 else []):
                out.at[idx, "rank"] = int(ranks[idx])
    order = {m: i for i, m in enumerate(execution_order(out["execution"]))}
    out = out.assign(_m=out["execution"].map(order), _l=out["method"].map(lambda m: label_order(method_label(m))))
    if lifelong:
        out = out.assign(_t=out["task"].map(TASKS.index))
    ordered = out.sort_values((["_t"] if lifelong else []) + ["n_robots", "loss_p", "_m", "_l", "method"])
    return ordered.drop(columns=["_m", "_l", *(["_t"] if lifelong else [])]).reset_index(drop=True)


FILTER_RATES = ("correction_rate", "fallback_rate")


def filter_note(board: pd.DataFrame) -> str:
    """`` `` + ``FILTER_NOTE`` where a row of ``board`` has a method's filter rates beside its score, else ""."""
    filtered = set(FILTER_RATES) <= set(board) and board[list(FILTER_RATES)].notna().to_numpy().any()
    return " " + FILTER_NOTE if filtered else ""


def _with_filter_rates(board: pd.DataFrame, evals: pd.DataFrame) -> pd.DataFrame:
    """``board`` with each row's correction and fallback rate (``safety_frame``'s: means over
    seeds, NaN for a method that runs no safety filter), shown beside its score (issue 47
    item 3, docs/decisions/0236). Rows without those columns (hand-made frames) get NaN."""
    keys = ["method", "n_robots", "loss_p", "execution"]
    if board.empty or not set(SAFETY) <= set(evals):
        return board.assign(**{c: np.nan for c in FILTER_RATES})
    rates = safety_frame(evals)[[*keys, *FILTER_RATES]]
    return board.merge(rates, on=keys, how="left", validate="many_to_one")


def score_matrices(evals: pd.DataFrame, mode: str, metric: str = "success_rate",
                   ) -> tuple[dict[str, np.ndarray], list[tuple[int, float]], dict[str, int]]:
    """Per method, its (seeds x configurations) ``metric`` matrix in mode ``mode`` (a planner in
    ``planner``) over the configurations every method covers, using the seeds every one of
    those configurations has; the configurations; the seeds used per method."""
    scores = seed_scores(evals, metric)
    scores = scores[(scores["execution"] == mode) | (scores["execution"] == PLANNER)]
    methods = _methods(scores)
    configs = None
    for m in methods:
        have = set(map(tuple, scores.loc[scores["method"] == m, ["n_robots", "loss_p"]].drop_duplicates().to_numpy()))
        configs = have if configs is None else configs & have
    cfgs = sorted((int(n), float(p)) for n, p in (configs or set()))
    mats, used = {}, {}
    for m in methods:
        part = scores[scores["method"] == m]
        per = [part[(part["n_robots"] == n) & np.isclose(part["loss_p"], p)] for n, p in cfgs]
        seeds = sorted(set.intersection(*(set(g["seed"]) for g in per))) if per else []
        if not seeds:
            continue
        mats[m] = np.stack([g.set_index("seed").loc[seeds, metric].to_numpy() for g in per], axis=1)
        used[m] = len(seeds)
    return mats, cfgs, used


def _profile(taus: np.ndarray):
    """rliable's score distribution at each of ``taus``: the fraction of the matrix's scores
    (every seed of every configuration) above tau, batched; returned shaped (len(taus), ...)."""
    def stat(*cols: np.ndarray, axis: int = -1) -> np.ndarray:
        flat = np.concatenate([np.moveaxis(c, axis, -1) for c in cols], axis=-1)
        return np.moveaxis((flat[..., None, :] > taus[:, None]).mean(axis=-1), -1, 0)
    return stat


def aggregate_frame(evals: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(IQM per mode and method, probability of improvement per mode and ordered pair) over
    the configurations every method covers; see the module docstring. The score is each
    task's own (``reports.tables.mapf.SCORE``): success of one-shot cells, throughput of
    lifelong cells, each task aggregated apart; a run with lifelong cells gets a ``task``
    column (docs/decisions/0221, 0235)."""
    iqm_rows, poi_rows = [], []
    lifelong = has_lifelong(evals)
    tag = (lambda t: {"task": t}) if lifelong else (lambda t: {})
    for task in tasks_of(evals):
        part, metric = _task_rows(evals, task), SCORE[task]
        modes = [m for m in execution_order(part["execution"]) if m != PLANNER] or [PLANNER]
        for mode in modes:
            mats, cfgs, used = score_matrices(part, mode, metric)
            for m, mat in mats.items():
                per_seed = np.array([iqm(row) for row in mat])  # each seed's IQM across the configurations
                kind = "positive" if metric == "throughput" else "rate"  # goals per step: no upper bound
                mean, lo, hi = (positive_ci if kind == "positive" else rate_ci)(per_seed, LEVEL)
                sd = float(per_seed.std(ddof=1)) if len(per_seed) > 1 else np.nan
                iqm_rows.append({**tag(task), "execution": mode, "method": m, "label": method_label(m),
                                 "configurations": len(cfgs), "seeds": used[m],
                                 "iqm": float(rly_metrics.aggregate_iqm(mat)),
                                 "seed_iqm": mean, "iqm_lo": lo, "iqm_hi": hi,
                                 "iqm_cov": coverage(kind, mean, sd, len(per_seed), COVERAGE_SIMS, LEVEL)})
            covered: dict[frozenset[str], float] = {}  # Y over X covers as X over Y (the interval mirrors)
            for x, y in permutations(mats, 2):
                a, b = mats[x], mats[y]
                k = a.shape[1]
                cols = [a[:, j] for j in range(k)] + [b[:, j] for j in range(k)]
                lo, hi = stratified_ci(cols, poi_statistic(k))
                pair = frozenset((x, y))
                if pair not in covered:
                    covered[pair] = poi_coverage(a, b, "positive" if metric == "throughput" else "rate")
                poi_rows.append({**tag(task), "execution": mode, "method": x, "over": y, "label": method_label(x),
                                 "over_label": method_label(y), "configurations": k,
                                 "poi": float(rly_metrics.probability_of_improvement(a, b)),
                                 "poi_lo": lo, "poi_hi": hi, "poi_cov": covered[pair]})
    return pd.DataFrame(iqm_rows), pd.DataFrame(poi_rows)


def safety_frame(evals: pd.DataFrame) -> pd.DataFrame:
    """Per method, N, p and mode: seeds and the mean over seeds of each column of ``SAFETY``
    (NaN when the method never ran a filter: its rows hold NaN for fallbacks and candidates,
    and 0 corrections, which this table shows as NaN too: nothing was there to correct)."""
    keys = ["method", "n_robots", "loss_p", "execution"]
    if "safety_filter" in evals:
        evals = evals.assign(correction_rate=evals["correction_rate"].where(evals["safety_filter"].astype(bool)))
    per_seed = evals.groupby([*keys, "seed"], sort=True)[list(SAFETY)].mean().reset_index()
    out = per_seed.groupby(keys, sort=True).agg(seeds=("seed", "nunique"), **{c: (c, "mean") for c in SAFETY})
    out = out.reset_index()
    out.insert(1, "label", out["method"].map(method_label))
    return out


SUCCESS_NOTE = ("Success rate (robots at their goal per episode): the mean over seeds of per-seed means, "
                "[95% CI over seeds: a Student t interval on the logit scale, inside 0-100% by construction; "
                "'uninformative' where it spans more than 80 points], (its coverage of the true mean simulated "
                "at the row's own mean, spread and seeds, Beta-distributed); where that coverage is under 93% "
                "(seeds collapsed: with one seed near 0 and the others high, three seeds often all land on "
                "one side, and no interval over three values then covers) the row prints its mean and "
                "'interval not trusted' with the coverage, no interval (docs/decisions/0233); "
                "rank 1 = highest mean among the methods at that "
                "configuration and mode (a planner's one mode ranks with every learned mode).")
LIFELONG_NOTE = ("A lifelong run: robots get a new goal whenever they reach one, so success (robots at their "
                 "goal at the end) says little; throughput (goals reached per step) is the score. Both: the mean "
                 "over seeds of per-seed means, [95% CI over seeds, inside the range by construction: a "
                 "Student t interval on the logit scale (success), Cox's lognormal interval (throughput)] "
                 "(simulated coverage; under 93%: no interval, 'interval not trusted'); "
                 "rank 1 = highest mean throughput "
                 "among the methods at that configuration and mode (a planner's one mode ranks with every "
                 "learned mode).")
MIXED_NOTE = ("This run holds one-shot and lifelong cells. Each task is ranked by its own score, in its own "
              "tables: one-shot cells by success, lifelong cells by throughput (goals reached per step); no "
              "rank, aggregate or comparison puts a throughput beside a success (docs/decisions/0235).")
POI_COVERAGE_NOTE = ("Beside each interval, its simulated coverage: the same bootstrap on data sets drawn per "
                     "configuration from a Beta (success) or lognormal (throughput) at each method's own mean and "
                     "s.d. over seeds, a point mass where every seed agreed; under 93% the interval is not printed "
                     "(docs/decisions/0233, 0239). \"Coverage not simulated\": the models order every "
                     "configuration with certainty but the seeds do not (ties at exactly 0% or 100%, which a Beta "
                     "never draws), so no simulation speaks for that interval.")
# the index's short form of ``untrusted_text`` (leaderboard.md has the coverage)
UNTRUSTED_SHORT = "[interval not trusted]"
TASK_HEADING = {"one-shot": "One-shot cells: ranked by success",
                "lifelong": "Lifelong cells: ranked by throughput (goals reached per step)"}


def _pct(v: float) -> str:
    return "—" if not np.isfinite(v) else f"{100 * v:.1f}%"


def _interval(point: str, interval: str, cov: float) -> str:
    """A headline interval with its simulated coverage, or, where that coverage is under 93%,
    the point and no interval (docs/decisions/0233)."""
    if not trusted(cov):
        return f"{point} ({untrusted_text(cov)})"
    return interval + ("" if not np.isfinite(cov) else f" (coverage {cov:.1%})")


def _num_ci(v: float, lo: float, hi: float, cov: float) -> str:
    """A throughput with its interval and coverage, as the leaderboard prints it."""
    return _interval(fmt_ci(v, np.nan, np.nan, "num"), fmt_ci(v, lo, hi, "num"), cov)


def _ci(v: float, lo: float, hi: float, cov: float = np.nan) -> str:
    """A rate with its interval, as the leaderboard prints it."""
    if not np.isfinite(lo):
        return _pct(v)
    vague = "; uninformative" if uninformative(lo, hi) else ""
    return _interval(_pct(v), _pct(v) + f" [{_pct(lo)}, {_pct(hi)}{vague}]", cov)


def _of_task(frame: pd.DataFrame, task: str) -> pd.DataFrame:
    """The rows of ``task`` of a score frame (all of them in a frame without ``task``: one-shot)."""
    return frame[frame["task"] == task] if "task" in frame else frame


def _board_tasks(board: pd.DataFrame) -> list[str]:
    """The tasks of a score frame's rows, in report order."""
    return [t for t in TASKS if t in set(board["task"])] if "task" in board else ["one-shot"]


def _score_lines(board: pd.DataFrame, task: str) -> list[str]:
    """The per-configuration table of one task's rows."""
    if task == "lifelong":
        lines = ["| N | p | execution | method | seeds | throughput (goals/step) [95% CI] | success [95% CI] | rank |",
                 "|---|---|---|---|---|---|---|---|"]
        for r in board.itertuples(index=False):
            lines.append(f"| {r.n_robots} | {fmt_p(r.loss_p)} | {r.execution} | {r.label} | {r.seeds} | "
                         f"{_num_ci(r.throughput, r.throughput_lo, r.throughput_hi, r.throughput_cov)}"
                         f"{filter_text(r.correction_rate, r.fallback_rate)} | "
                         f"{_ci(r.success, r.success_lo, r.success_hi, r.success_cov)} | {r.rank} |")
        return lines
    lines = ["| N | p | execution | method | seeds | success [95% CI] | rank |", "|---|---|---|---|---|---|---|"]
    for r in board.itertuples(index=False):
        lines.append(f"| {r.n_robots} | {fmt_p(r.loss_p)} | {r.execution} | {r.label} | {r.seeds} | "
                     f"{_ci(r.success, r.success_lo, r.success_hi, r.success_cov)}"
                     f"{filter_text(r.correction_rate, r.fallback_rate)} | {r.rank} |")
    return lines


def _aggregate_lines(iqm: pd.DataFrame, poi: pd.DataFrame, task: str) -> list[str]:
    """IQM and probability of improvement of one task's score across its configurations."""
    score = SCORE_NAME[task]
    interval = "Cox's lognormal interval" if task == "lifelong" else "a Student t interval on the logit scale"
    lines = [f"Interquartile mean (rliable) of the seed x configuration {score} matrix over the "
             "configurations every method covers; seeds: those every such configuration of the method "
             "has. The interval is over seeds, the unit: each seed's IQM across the configurations, "
             f"their mean [95% CI: {interval}] (its simulated coverage at "
             "their own mean, spread and seeds). A stratified bootstrap over 3 seeds per configuration "
             "covered 80-88% (docs/decisions/0232).", ""]
    if iqm.empty:
        return lines + ["No configuration is covered by every method.", ""]
    head = "IQM throughput (goals/step)" if task == "lifelong" else "IQM success"
    lines += [f"| execution | method | configurations | seeds | {head} | seeds' mean IQM [95% CI] |",
              "|---|---|---|---|---|---|"]
    for r in iqm.itertuples(index=False):
        point = f"{r.iqm:.3g}" if task == "lifelong" else _pct(r.iqm)
        interval_txt = (_num_ci(r.seed_iqm, r.iqm_lo, r.iqm_hi, r.iqm_cov)
                        if task == "lifelong" else _ci(r.seed_iqm, r.iqm_lo, r.iqm_hi, r.iqm_cov))
        lines.append(f"| {r.execution} | {r.label} | {r.configurations} | {r.seeds} | {point} | {interval_txt} |")
    lines += ["", f"Probability of improvement P(X > Y) in {score} (rliable: Mann-Whitney over seeds, averaged "
              f"over configurations) [95% stratified bootstrap CI]; 50% = no difference. {POI_COVERAGE_NOTE}"
              if task == "lifelong" else
              "Probability of improvement P(X > Y) (rliable: Mann-Whitney over seeds, averaged over "
              f"configurations) [95% stratified bootstrap CI]; 50% = no difference. {POI_COVERAGE_NOTE}", "",
              "| execution | X | Y | P(X > Y) [95% CI] |", "|---|---|---|---|"]
    for r in poi.itertuples(index=False):
        unsimulated = " (coverage not simulated)" if np.isfinite(r.poi_lo) and not np.isfinite(r.poi_cov) else ""
        lines.append(f"| {r.execution} | {r.label} | {r.over_label} | {_ci(r.poi, r.poi_lo, r.poi_hi, r.poi_cov)}"
                     f"{unsimulated} |")
    return lines


def leaderboard_markdown(board: pd.DataFrame, iqm: pd.DataFrame, poi: pd.DataFrame, safety: pd.DataFrame) -> str:
    """The leaderboard page: per configuration, aggregates, pairwise improvement, safety; each
    task ranked and aggregated by its own score, apart (docs/decisions/0235)."""
    lines = ["# Leaderboard: every method of the run", "", SUCCESS_NOTE, ""]
    if board.empty:
        return "\n".join(lines + ["No evaluated cell yet.", ""])
    tasks = _board_tasks(board)
    mixed = len(tasks) > 1
    lines[-2] = MIXED_NOTE if mixed else LIFELONG_NOTE if tasks == ["lifelong"] else SUCCESS_NOTE
    if filter_note(board):
        lines += [FILTER_NOTE, ""]
    for task in tasks:
        if mixed:
            lines += [f"## {TASK_HEADING[task]}", "", LIFELONG_NOTE if task == "lifelong" else SUCCESS_NOTE, ""]
        lines += _score_lines(_of_task(board, task), task)
    for task in tasks:
        lines += ["", "## Across configurations" + (f": {task} cells" if mixed else ""), ""]
        lines += _aggregate_lines(_of_task(iqm, task), _of_task(poi, task), task)
    lines += ["", "## Safety and payload of every method", "",
              "Means over seeds; correction rate, fallback rate and candidates are NaN (—) where no "
              "safety filter ran; payload: the scalars the method reported sending per step.", "",
              "| method | N | p | execution | seeds | collision rate | correction rate | fallback rate | "
              "candidates | payload (scalars/step) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in safety.itertuples(index=False):
        cand = "—" if not np.isfinite(r.mean_candidates) else f"{r.mean_candidates:.1f}"
        pay = "—" if not np.isfinite(r.payload_scalars_per_step) else f"{r.payload_scalars_per_step:,.1f}"
        coll = (_pct(r.collision_rate) if r.collision_rate >= 1e-3 or r.collision_rate == 0
                else f"{100 * r.collision_rate:.3g}%")
        lines.append(f"| {r.label} | {r.n_robots} | {fmt_p(r.loss_p)} | {r.execution} | {r.seeds} | {coll} | "
                     f"{_pct(r.correction_rate)} | {_pct(r.fallback_rate)} | {cand} | {pay} |")
    return "\n".join(lines) + "\n"


def leaderboard_display(board: pd.DataFrame) -> pd.DataFrame:
    """The per-configuration leaderboard as the index page shows it (one row per
    configuration and mode, one column per method: its task's score [95% CI] (rank):
    success of a one-shot cell, throughput of a lifelong one; a run of both tasks gets a
    ``task`` column, so no row holds both)."""
    if board.empty:
        return pd.DataFrame()

    def cell(r: pd.Series) -> str:
        if r.get("task") == "lifelong":  # its score (docs/decisions/0218, 0235)
            shown = (fmt_ci(r["throughput"], r["throughput_lo"], r["throughput_hi"], "num")
                     if trusted(r["throughput_cov"]) else f"{fmt_ci(r['throughput'], np.nan, np.nan, 'num')} "
                     f"{UNTRUSTED_SHORT}")
            return f"{shown} ({int(r['rank'])}){filter_text(r['correction_rate'], r['fallback_rate'])}"
        lo = ("" if not np.isfinite(r["success_lo"]) else
              f" [{100 * r['success_lo']:.1f}, {100 * r['success_hi']:.1f}]" if trusted(r["success_cov"])
              else f" {UNTRUSTED_SHORT}")  # docs/decisions/0233
        return (f"{100 * r['success']:.1f}%{lo} ({int(r['rank'])})"
                f"{filter_text(r['correction_rate'], r['fallback_rate'])}")

    mixed = len(_board_tasks(board)) > 1
    keys = ["task", "n_robots", "p", "execution"] if mixed else ["n_robots", "p", "execution"]
    shown = board.assign(value=board.apply(cell, axis=1), p=board["loss_p"].map(fmt_p))
    wide = shown.pivot_table(index=keys, columns="label", values="value", aggfunc="first",
                             sort=False).reset_index()
    labels = [method_label(m) for m in _methods(board)]
    return wide[[*keys, *[c for c in labels if c in wide]]].rename(columns={"n_robots": "N"}).fillna("")


def success_figure(board: pd.DataFrame, against: str, score: str = "success") -> Built:
    """Success (or with ``score="throughput"`` a lifelong run's throughput) with its 95% CI
    over seeds against ``against`` ("n_robots" or "loss_p"), one panel per value of the
    other axis, one row per learned execution mode (planners drawn in every row), every
    method of the run in its declared colour."""
    name = "success rate" if score == "success" else "throughput (goals/step)"
    other = "loss_p" if against == "n_robots" else "n_robots"
    modes = [m for m in execution_order(board["execution"]) if m != PLANNER] or [PLANNER] if len(board) else []
    panels = sorted(board[other].unique()) if len(board) else []
    with paper_style():
        fig = new_figure(1.5 * max(len(modes), 1) + 0.4, 3.5 if len(panels) <= 2 else 7.0)
        if not len(board):
            placeholder(fig.add_subplot(), "no evaluated cell yet")
            return Built(fig, ["no evaluated cell"], "")
        axes = fig.subplots(len(modes), len(panels), squeeze=False, sharey=True)
        for i, mode in enumerate(modes):
            for j, val in enumerate(panels):
                ax = axes[i][j]
                part = board[np.isclose(board[other], val) & board["execution"].isin([mode, PLANNER])]
                for m in _methods(part):
                    g = part[part["method"] == m].sort_values(against)
                    x = g[against].to_numpy(dtype=float)
                    ax.plot(x, g[score], marker="o", ls=method_style(m), color=method_color(m),
                            label=method_label(m), ms=2.5)
                    shown = g[f"{score}_cov"].map(trusted).to_numpy(dtype=bool)  # decision 0233: no band there
                    ax.plot(x[~shown], g[score].to_numpy(dtype=float)[~shown], ls="none", marker="o", ms=4.5,
                            mfc="white", mec=method_color(m), mew=0.8)
                    ax.fill_between(x, g[f"{score}_lo"].where(shown), g[f"{score}_hi"].where(shown),
                                    color=method_color(m), alpha=0.15, lw=0)
                if score == "success":
                    ax.set_ylim(-0.02, 1.02)
                ax.set_title(f"{'p' if other == 'loss_p' else 'N'} = {fmt_p(val) if other == 'loss_p' else int(val)}, "
                             f"{mode}")
                ax.set_xticks(sorted(part[against].unique()) if len(part) else [])
                if i == len(modes) - 1:
                    ax.set_xlabel("team size N" if against == "n_robots" else "loss probability p")
                if j == 0:
                    ax.set_ylabel(name)
        if score != "success":  # from 0 to every panel's top (shared y: one panel's autoscale would cut the others)
            top = float(np.nanmax(board[[score, f"{score}_hi"]].to_numpy(dtype=float), initial=0.0))
            axes[0][0].set_ylim(0.0, 1.05 * top if top > 0 else 1.0)
        handles, labels = ranked_legend(axes.flat)  # every method of any panel once
        fitted_legend(fig, handles, labels, "outside lower center")
    seeds = board.groupby("method")["seeds"].agg(["min", "max"])
    seed_text = "; ".join(f"{method_label(m)} {r['min']}" + (f"-{r['max']}" if r["max"] != r["min"] else "")
                          for m, r in seeds.iterrows())
    kind = "t on the logit scale" if score == "success" else "Cox's lognormal interval"
    caption = (f"{name.capitalize()} against {'team size N' if against == 'n_robots' else 'loss probability p'} "
               f"for every method of the run, mean over seeds with a 95% CI over seeds ({kind}) "
               f"(seeds per point: {seed_text}); no band and a hollow marker where the interval's simulated "
               f"coverage is under {COVERAGE_TARGET:.0%} (interval not trusted); one row per execution mode, "
               f"planners in every row.")
    return Built(fig, [], caption)


def profile_figure(evals: pd.DataFrame, task: str = "one-shot") -> Built:
    """Performance profiles: per method, the fraction of its (seed, configuration) runs whose
    score exceeds tau, over the configurations every method covers (argmax; planners),
    with a 95% stratified bootstrap band (seeds resampled within each configuration). The
    score is the task's (``evals``: that task's rows): success, or throughput (goals reached
    per step, tau from 0 to the largest value of the run)."""
    modes = [m for m in execution_order(evals["execution"]) if m != PLANNER] if len(evals) else []
    mode = modes[0] if modes else PLANNER
    mats, cfgs, used = score_matrices(evals, mode, SCORE[task]) if len(evals) else ({}, [], {})
    top = max((float(np.nanmax(m)) for m in mats.values()), default=1.0) if task == "lifelong" else 1.0
    taus = np.linspace(0.0, top if np.isfinite(top) and top > 0 else 1.0, 101)
    score = "success" if task == "one-shot" else "throughput"
    with paper_style():
        fig = new_figure(2.9)
        ax = fig.add_subplot()
        if not mats:
            placeholder(ax, "no configuration covered by every method")
            return Built(fig, ["no configuration covered by every method"], "")
        profile = _profile(taus)
        for m, mat in mats.items():
            cols = [mat[:, j] for j in range(mat.shape[1])]
            ax.plot(taus, profile(*cols), color=method_color(m), ls=method_style(m), label=method_label(m))
            lo, hi = stratified_band(cols, profile)
            if lo.ndim:  # no band with a single seed
                ax.fill_between(taus, lo, hi, color=method_color(m), alpha=0.15, lw=0)
        ax.set_xlabel(r"success rate $\tau$" if task == "one-shot" else r"throughput $\tau$ (goals/step)")
        ax.set_ylabel(rf"fraction of runs with {score} $> \tau$")
        handles, labels = ax.get_legend_handles_labels()  # below the axes: curves run through every corner
        fig.legend(handles, labels, loc="outside lower center", ncol=min(len(labels), 2), frameon=False)
    scale = ("" if task == "one-shot" else " Throughput is not normalized: configurations with more robots reach "
             "more goals per step, so the profile mixes scales (the per-configuration leaderboard compares like "
             "with like).")
    caption = (f"Performance profiles{' of lifelong cells' if task == 'lifelong' else ''} ({mode} execution; "
               f"planners in their own mode): the fraction of each "
               f"method's (seed, configuration) runs with {score} above tau, over the {len(cfgs)} "
               f"configurations every method covers (seeds per method: "
               + ", ".join(f"{method_label(m)} {k}" for m, k in used.items())
               + "); shaded: 95% stratified bootstrap CI (seeds resampled within each configuration)." + scale)
    return Built(fig, [], caption)


FIGURE_STEMS = {"one-shot": ("success_vs_n", "success_vs_p", "performance_profiles"),
                "lifelong": ("throughput_vs_n", "throughput_vs_p", "performance_profiles")}


def score_figures(board: pd.DataFrame, evals: pd.DataFrame) -> list[tuple[str, Built]]:
    """The leaderboard's figures, (file stem, figure): per task of the run, its score against N
    and against p and its performance profiles, one-shot first; a lifelong run draws
    throughput, never success (docs/decisions/0235). In a run of both tasks the lifelong
    profiles are ``performance_profiles_lifelong``."""
    tasks = _board_tasks(board) if len(board) else ["one-shot"]
    out = []
    for task in tasks:
        sub, rows = _of_task(board, task), _task_rows(evals, task) if len(evals) else evals
        vs_n, vs_p, profiles = FIGURE_STEMS[task]
        out += [(vs_n, success_figure(sub, "n_robots", SCORE_NAME[task])),
                (vs_p, success_figure(sub, "loss_p", SCORE_NAME[task])),
                (profiles + ("_lifelong" if task == "lifelong" and len(tasks) > 1 else ""),
                 profile_figure(rows, task))]
    return out
