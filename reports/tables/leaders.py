"""Who leads where: per configuration and learned execution mode, the leading learned method
(docs/decisions/0194).

A pure function of the per-seed success scores (``leaderboard.seed_scores``), the seed as
the unit, as the rest of the leaderboard:

* ``leaders_frame``: per (N, p) and learned execution mode, among the learned methods with
  that mode, the leader (highest mean success over seeds) and the runner-up, the leader's
  margin over the runner-up with a 95% CI over seeds (Newcombe's square-and-add of the two
  rates' ``reports.stats.rate_ci``, inside [-1, 1] by construction),
  and the best planner at that configuration (kept out of the race: PIBT plans with full
  information, a ceiling rather than a rival) with the leader's gap to it, with the same CI;
* ``leaders_markdown`` / ``leaders_display``: one N x p matrix per mode, how many
  configurations each method leads, and where another method than the one leading most
  leads (where the ordering changes with N or p);
* ``per_method_frame`` / ``per_method_markdown``: per learned execution mode and learned method,
  how many configurations it leads and how far it stays from the best planner at each
  configuration it shares with one (its own gap, leader or not).

The leader is picked by its mean, and each interval is pointwise (not corrected for the
N x p configurations): a margin whose interval excludes 0 is written ">", otherwise "≈".
That is a description of the run, not a claim check (those are in claims.md, calibrated).
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from reports.data.store import execution_order, fmt_p
from reports.figures.plotting import label_order, method_label
from reports.stats import positive_ci, rate_ci
from reports.tables.leaderboard import PLANNER, task_scores
from reports.tables.mapf import TASKS

PER_METHOD_COLUMNS = ["execution", "method", "configurations", "contested", "leads", "separated_leads",
                      "with_planner", "gap_min", "gap_max", "below_planner", "above_planner"]
COLUMNS = ["n_robots", "loss_p", "execution", "methods", "leader", "leader_success", "runner_up",
           "runner_up_success", "margin", "margin_lo", "margin_hi", "planner", "planner_success",
           "gap_to_planner", "gap_lo", "gap_hi"]


SCORED = {"leader_success", "runner_up_success", "planner_success"}  # "_score" in a run with lifelong cells


def columns(lifelong: bool) -> list[str]:
    """leaders.csv's columns: ``COLUMNS``, or with a ``task`` column and each score named
    ``_score`` (success of a one-shot row, throughput of a lifelong one) in a run with
    lifelong cells (docs/decisions/0235)."""
    if not lifelong:
        return COLUMNS
    return ["task", *[c.replace("_success", "_score") if c in SCORED else c for c in COLUMNS]]


def _ranked(group: pd.DataFrame) -> list[tuple[str, np.ndarray]]:
    """(method, per-seed scores) by decreasing mean score, ties in legend order."""
    per = [(m, g["score"].to_numpy()) for m, g in group.groupby("method")]
    return sorted(per, key=lambda t: (-float(np.nanmean(t[1])), label_order(method_label(t[0])), t[0]))


def leaders_frame(evals: pd.DataFrame) -> pd.DataFrame:
    """One row per (N, p, learned execution mode) that has a learned method; see the module
    docstring. Runner-up and margin are empty (NaN) where one learned method ran; planner
    and gap where no planner ran at that configuration. Each task races apart by its own
    score (a run with lifelong cells: ``columns(True)``)."""
    scores = task_scores(evals)
    lifelong = bool(scores["task"].eq("lifelong").any())
    rows = []
    modes = [m for m in execution_order(scores["execution"]) if m != PLANNER]
    for (task, n, p), cfg in _by_task(scores, ["n_robots", "loss_p"]):
        planners = _ranked(cfg[cfg["execution"] == PLANNER])
        for mode in modes:
            ranked = _ranked(cfg[cfg["execution"] == mode])
            if not ranked:
                continue
            (lead, a), rest = ranked[0], ranked[1:]
            row = {**({"task": task} if lifelong else {}), "n_robots": int(n), "loss_p": float(p),
                   "execution": mode, "methods": len(ranked),
                   "leader": lead, "leader_success": float(np.nanmean(a)), "runner_up": "", "planner": ""}
            if rest:
                second, b = rest[0]
                margin, lo, hi = _diff(a, b, task)
                row.update(runner_up=second, runner_up_success=float(np.nanmean(b)),
                           margin=margin, margin_lo=lo, margin_hi=hi)
            if planners:
                best, c = planners[0]
                gap, lo, hi = _diff(a, c, task)
                row.update(planner=best, planner_success=float(np.nanmean(c)),
                           gap_to_planner=gap, gap_lo=lo, gap_hi=hi)
            rows.append({k.replace("_success", "_score") if lifelong and k in SCORED else k: v
                         for k, v in row.items()})
    return pd.DataFrame(rows, columns=columns(lifelong))  # what a row leaves out is NaN


def _by_task(scores: pd.DataFrame, keys: list[str]) -> list[tuple[tuple, pd.DataFrame]]:
    """``scores`` grouped by (task, *keys), one-shot first, then by the keys."""
    groups = list(scores.groupby(["task", *keys]))
    return sorted(groups, key=lambda t: (TASKS.index(t[0][0]), *t[0][1:]))


def per_method_frame(evals: pd.DataFrame, leaders: pd.DataFrame) -> pd.DataFrame:
    """One row per (learned execution mode, learned method), in mode then legend order:
    ``configurations`` it ran at, ``contested`` (with another learned method), ``leads`` and
    ``separated_leads`` among those (``leaders``: ``leaders_frame(evals)``), and at the
    ``with_planner`` configurations a planner shares with it, its own score minus the
    best planner's: the range of the means (``gap_min``, ``gap_max``) and at how many the
    95% CI lies below 0 (``below_planner``) or above 0 (``above_planner``). In a run with
    lifelong cells, one row per task too (a ``task`` column first)."""
    scores = task_scores(evals)
    lifelong = "task" in leaders
    planners = {key: _ranked(cfg)[0][1] for key, cfg in _by_task(scores[scores["execution"] == PLANNER],
                                                                   ["n_robots", "loss_p"])}
    rows = []
    for task in TASKS if lifelong else ["one-shot"]:
        of_task = leaders[leaders["task"] == task] if lifelong else leaders
        for mode in execution_order(of_task["execution"]):
            part = of_task[of_task["execution"] == mode]
            contested = _contested(part)
            shared = set(contested.set_index(["n_robots", "loss_p"]).index)  # (N, p) with another learned method
            mine = scores[(scores["execution"] == mode) & (scores["task"] == task)]
            for method in sorted(mine["method"].unique(), key=lambda m: (label_order(method_label(m)), m)):
                runs = {(n, p): g for (_, n, p), g in _by_task(mine[mine["method"] == method],
                                                                ["n_robots", "loss_p"])}
                led = contested[contested["leader"] == method]
                gaps = np.array([_diff(g["score"].to_numpy(), planners[(task, *key)], task)
                                 for key, g in runs.items() if (task, *key) in planners]).reshape(-1, 3)
                rows.append({**({"task": task} if lifelong else {}), "execution": mode, "method": method,
                             "configurations": len(runs),
                             "contested": len(shared & runs.keys()), "leads": len(led),
                             "separated_leads": _separated(led), "with_planner": len(gaps),
                             "gap_min": gaps[:, 0].min() if len(gaps) else np.nan,
                             "gap_max": gaps[:, 0].max() if len(gaps) else np.nan,
                             "below_planner": int((gaps[:, 2] < 0).sum()),
                             "above_planner": int((gaps[:, 1] > 0).sum())})
    return pd.DataFrame(rows, columns=(["task"] if lifelong else []) + PER_METHOD_COLUMNS)


def per_method_display(per_method: pd.DataFrame) -> pd.DataFrame:
    """``per_method_frame`` as readers see it, one string per cell (the index page's table;
    ``per_method_markdown`` writes the same cells): leads "k of n" among the configurations
    shared with another learned method ("— (alone)" where there are none), and the gap to
    the best planner as the range of the means and "below / above of n" (in percentage points
    of success, or goals per step of throughput for lifelong rows; a run of both tasks gets a
    ``task`` column)."""
    tasks = _tasks(per_method)
    rows = []
    for _, r in per_method.iterrows():
        task = str(r.get("task", "one-shot"))
        leads = f"{r['leads']} of {r['contested']}" if r["contested"] else "— (alone)"
        separated = str(r["separated_leads"]) if r["contested"] else "—"
        if r["with_planner"]:
            gap = _span(_delta(r["gap_min"], task), _delta(r["gap_max"], task))
            below = f"{r['below_planner']} / {r['above_planner']} of {r['with_planner']}"
        else:
            gap = below = "—"
        rows.append(((task,) if len(tasks) > 1 else ()) + (r["execution"], method_label(r["method"]), leads,
                                                             separated, gap, below))
    gap_head = {"one-shot": "success − best planner, pp", "lifelong": "throughput − best planner, goals/step"}
    return pd.DataFrame(rows, columns=(["task"] if len(tasks) > 1 else []) + [
        "mode", "method", "leads", "by a separated margin",
        gap_head[tasks[0]] if len(tasks) == 1 else "score − best planner (pp of success; goals/step of throughput)",
        "CI below / above 0"])


def _tasks(frame: pd.DataFrame) -> list[str]:
    """The tasks of a leaders or per-method frame, in report order (one-shot without a ``task`` column)."""
    return [t for t in TASKS if t in set(frame["task"])] or ["lifelong"] if "task" in frame else ["one-shot"]


def per_method_markdown(per_method: pd.DataFrame) -> str:
    """``per_method_display`` as one markdown table (leaders.md's first section; the README's
    full-grid block is a copy of it)."""
    shown = per_method_display(per_method)
    lines = ["| " + " | ".join(shown.columns) + " |", "|" + "---|" * len(shown.columns)]
    lines += ["| " + " | ".join(row) + " |" for row in shown.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def _diff(a: np.ndarray, b: np.ndarray, task: str = "one-shot") -> tuple[float, float, float]:
    """mean(a) - mean(b) of two scores with its 95% interval over seeds: Newcombe's
    square-and-add (MOVER) combination of each side's interval (``rate_ci`` of a success,
    inside [-1, 1] by construction; Cox's ``positive_ci`` of a throughput) (docs/decisions/0232)."""
    ci = positive_ci if task == "lifelong" else rate_ci
    m1, l1, u1 = ci(a)
    m2, l2, u2 = ci(b)
    d = float(m1 - m2)
    return d, float(d - np.hypot(m1 - l1, u2 - m2)), float(d + np.hypot(u1 - m1, m2 - l2))


def _pp(v: float) -> str:
    return f"{100 * v:+.1f}"


def _percent(v: float) -> str:
    return f"{100 * v:.1f}%"


def _delta(v: float, task: str) -> str:
    """A difference of two scores: percentage points of success, goals per step of throughput."""
    return _pp(v) if task == "one-shot" else f"{v:+.3f}"


def _value(v: float, task: str) -> str:
    """A score: a success in percent, a throughput in goals per step."""
    return _percent(v) if task == "one-shot" else f"{v:.3g}"


def _span(lo: str, hi: str) -> str:
    """``lo`` where both ends print alike, else ``lo to hi``."""
    return lo if lo == hi else f"{lo} to {hi}"


def _score(r: pd.Series, who: str) -> float:
    """``who``'s ("leader", "runner_up", "planner") mean score in a row of ``leaders_frame``."""
    return float(r[f"{who}_score"] if f"{who}_score" in r else r[f"{who}_success"])


def _cell(r: pd.Series, full: bool) -> str:
    """``Leader 84.3% > Runner-up 48.5% (+35.8 pp [+6.1, +65.5])``, or without the rates and
    the interval (``full=False``: the index page's narrow cells); ``Leader 61.4% (only
    learned method)``. A lifelong row: throughputs and a margin in goals per step."""
    task = str(r.get("task", "one-shot"))
    rate = (lambda v: f" {_value(v, task)}") if full else (lambda v: "")
    head = f"{method_label(r['leader'])}{rate(_score(r, 'leader'))}"
    if not r["runner_up"]:
        return f"{head} (only learned method)"
    ci = (f" [{_delta(r['margin_lo'], task)}, {_delta(r['margin_hi'], task)}]"
          if full and np.isfinite(r["margin_lo"]) else "")
    unit = "pp" if task == "one-shot" else "goals/step"
    return (f"{head} {_mark(r['margin_lo'])} {method_label(r['runner_up'])}{rate(_score(r, 'runner_up'))} "
            f"({_delta(r['margin'], task)} {unit}{ci})")


def leaders_display(frame: pd.DataFrame, full: bool = False) -> pd.DataFrame:
    """The matrices as one table: a row per (execution mode, N), a column per p (``full``:
    with the rates and the margin's CI, as leaders.md; else the leader, the runner-up and
    the margin, for the index page); a run of both tasks: a row per (task, mode, N)."""
    if frame.empty:
        return pd.DataFrame()
    keys = ["task", "execution", "n_robots"] if len(_tasks(frame)) > 1 else ["execution", "n_robots"]
    shown = frame.assign(text=frame.apply(_cell, axis=1, full=full), p=frame["loss_p"].map(lambda p: f"p = {fmt_p(p)}"))
    wide = shown.pivot_table(index=keys, columns="p", values="text", aggfunc="first").reset_index()
    order = {m: i for i, m in enumerate(execution_order(frame["execution"]))}
    wide = wide.assign(_m=wide["execution"].map(order))
    if "task" in keys:
        wide = wide.assign(_t=wide["task"].map(TASKS.index))
    wide = wide.sort_values([c for c in ("_t", "_m", "n_robots") if c in wide]).drop(
        columns=[c for c in ("_t", "_m") if c in wide])
    ps = [f"p = {fmt_p(p)}" for p in sorted(frame["loss_p"].unique())]
    return wide[[*keys, *ps]].rename(columns={"n_robots": "N"}).fillna("").reset_index(drop=True)


def _n(k: int, noun: str) -> str:
    """``1 configuration``, ``2 configurations``."""
    return f"{k} {noun}{'' if k == 1 else 's'}"


def _counts(part: pd.DataFrame) -> str:
    """``Decentralized leads 7 of 15 configurations with two or more learned methods (5 by a
    margin whose CI excludes 0); ...; 3 configurations have one learned method``."""
    contested = _contested(part)
    out = []
    for m, g in _by_leads(contested):
        out.append(f"{method_label(m)} leads {len(g)} of {_n(len(contested), 'configuration')} with two or more "
                   f"learned methods ({_separated(g)} by a margin whose CI excludes 0)")
    if len(contested) < len(part):
        alone = len(part) - len(contested)
        out.append(f"{_n(alone, 'configuration')} {'has' if alone == 1 else 'have'} one learned method")
    return "; ".join(out)


def _by_leads(contested: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    """The contested configurations per leader, the method leading most first (ties in legend order)."""
    return sorted(contested.groupby("leader"), key=lambda t: (-len(t[1]), label_order(method_label(t[0]))))


def _elsewhere(part: pd.DataFrame) -> str:
    """`` Where another method than Decentralized leads: N = 60, p = 0.6 (IC3Net ≈); ...``: where
    the ordering changes with N or p, as the configurations whose leader is not the method
    leading most; empty where one method leads every contested configuration."""
    contested = _contested(part)
    if contested["leader"].nunique() < 2:
        return ""
    top = _by_leads(contested)[0][0]
    places = "; ".join(f"N = {r.n_robots}, p = {fmt_p(r.loss_p)} ({method_label(r.leader)} {_mark(r.margin_lo)})"
                       for r in contested[contested["leader"] != top].itertuples())
    return f" Where another method than {method_label(top)} leads: {places}."


def _contested(part: pd.DataFrame) -> pd.DataFrame:
    """The rows (configurations) of ``part`` with two or more learned methods."""
    return part[part["runner_up"] != ""]


def _separated(rows: pd.DataFrame) -> int:
    """How many of ``rows`` lead by a margin whose CI excludes 0."""
    return int((rows["margin_lo"] > 0).sum())


def _mark(margin_lo: float) -> str:
    """">" where the margin's CI excludes 0, else "≈" (NaN, one learned method: "≈")."""
    return ">" if margin_lo > 0 else "≈"


def _planner_line(part: pd.DataFrame, task: str = "one-shot") -> str:
    """How far the leading learned method stays from the best planner, over the configurations."""
    have = part[part["planner"] != ""]
    if have.empty:
        return "no planner ran at these configurations."
    labels = ", ".join(sorted({method_label(m) for m in have["planner"]}))
    below, above = int((have["gap_hi"] < 0).sum()), int((have["gap_lo"] > 0).sum())

    rates, gaps = have.apply(_score, axis=1, who="planner"), have["gap_to_planner"]
    unit = "pp" if task == "one-shot" else "goals/step"
    return (f"the leading learned method's {SCORE_WORD[task]} minus the best planner's ({labels}: "
            f"{_span(_value(rates.min(), task), _value(rates.max(), task))}) is "
            f"{_span(_delta(gaps.min(), task), _delta(gaps.max(), task))} {unit}; its CI lies below 0 at {below} "
            f"and above 0 at {above} of the {_n(len(have), 'configuration')} with a planner.")


PER_METHOD_HEADING = "## Per method"  # leaders.md's section the README's full-grid block copies
SCORE_WORD = {"one-shot": "success", "lifelong": "throughput"}
INTRO = {
    "one-shot": ("the learned method with the highest mean success over seeds, then the runner-up, and the "
                 "leader's margin in percentage points [95% CI over seeds: the square-and-add of the two rates' "
                 "logit t intervals, inside ±100 points by construction]."),
    "lifelong": ("the learned method with the highest mean throughput (goals reached per step: a lifelong "
                 "run's score; success says little when every robot gets a new goal on arrival) over seeds, then "
                 "the runner-up, and the leader's margin in goals per step [95% CI over seeds: the "
                 "square-and-add of the two throughputs' Cox lognormal intervals]."),
    "mixed": ("each task races apart by its own score: among one-shot cells the learned method with the highest "
              "mean success over seeds, the runner-up and the margin in percentage points [95% CI over seeds: "
              "the square-and-add of the two rates' logit t intervals]; among lifelong cells the same by "
              "throughput (goals reached per step), the margin in goals per step [the square-and-add of the two "
              "throughputs' Cox lognormal intervals]; never a throughput against a success."),
}


def leaders_markdown(frame: pd.DataFrame, per_method: pd.DataFrame, tasks: list[str] | None = None) -> str:
    """The page ``leaders.md``: per learned method and mode, its leads and its distance to the
    planners (``per_method``: ``per_method_frame``); then per learned execution mode, the N x p
    matrix of leaders, how many configurations each method leads, and the leader's distance
    to the planners. ``tasks``: the run's (default: the frame's), each raced by its own score."""
    tasks = tasks or _tasks(frame)
    intro = INTRO[tasks[0]] if len(tasks) == 1 else INTRO["mixed"]
    lines = ["# Who leads where", "",
             f"Per configuration (team size N, loss probability p) and learned execution mode: {intro} "
             "\">\" where that interval excludes 0, \"≈\" where it does not. "
             "The leader is picked by its mean and the intervals are pointwise (not corrected for the number of "
             "configurations; where no method is better, \">\" appears at under 5% of them, simulated): this "
             "describes the run, the calibrated verdicts are in claims.md. Planners are "
             "listed apart, as a reference (PIBT plans with full information).", ""]
    if frame.empty:
        return "\n".join(lines + ["No learned method was evaluated yet.", ""])
    own = (f"its own {SCORE_WORD[tasks[0]]} minus the best planner's" if len(tasks) == 1
           else "its own score (its task's) minus the best planner's")
    lines += [PER_METHOD_HEADING, "",
              "Per learned method and mode: how many of the configurations it shares with another learned method "
              "it leads (and by a margin whose CI excludes 0), and at the configurations it shares with a planner, "
              f"{own} (the range of the means, and at how many the 95% CI "
              "lies below or above 0).", "", per_method_markdown(per_method)]
    display = leaders_display(frame, full=True)
    ps = [c for c in display.columns if c.startswith("p = ")]
    mixed = "task" in display
    for task in _tasks(frame):
        of_task = frame[frame["task"] == task] if "task" in frame else frame
        for mode in execution_order(of_task["execution"]):
            part = of_task[of_task["execution"] == mode]
            rows = display[(display["execution"] == mode) & (display["task"] == task if mixed else True)]
            lines += [f"## {mode}" + (f", {task} cells ({SCORE_WORD[task]})" if mixed else ""), "",
                      "| N | " + " | ".join(ps) + " |", "|---|" + "---|" * len(ps)]
            lines += [f"| {r['N']} | " + " | ".join(r[p] or "—" for p in ps) + " |" for _, r in rows.iterrows()]
            lines += ["", f"{_counts(part)}.{_elsewhere(part)} Against the planners: {_planner_line(part, task)}", ""]
    return "\n".join(lines)
