"""Who leads where: per configuration and learned execution mode, the leading learned method
(docs/decisions/0194).

A pure function of the per-seed success scores (``leaderboard.seed_scores``), the seed as
the unit, as the rest of the leaderboard:

* ``leaders_frame``: per (N, p) and learned execution mode, among the learned methods with
  that mode, the leader (highest mean success over seeds) and the runner-up, the leader's
  margin over the runner-up with a 95% Welch t CI over seeds (``reports.stats.t_test``),
  and the best planner at that configuration (kept out of the race: PIBT plans with full
  information, a ceiling rather than a rival) with the leader's gap to it, also with a
  Welch CI;
* ``leaders_markdown`` / ``leaders_display``: one N x p matrix per mode, and how many
  configurations each method leads.

The leader is picked by its mean, and each interval is pointwise (not corrected for the
N x p configurations): a margin whose interval excludes 0 is written ">", otherwise "≈".
That is a description of the run, not a claim check (those are in claims.md, calibrated).
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from reports.data.store import execution_order, fmt_p
from reports.figures.plotting import label_order, method_label
from reports.stats import cut_interval, t_test
from reports.tables.leaderboard import PLANNER, seed_scores

COLUMNS = ["n_robots", "loss_p", "execution", "methods", "leader", "leader_success", "runner_up",
           "runner_up_success", "margin", "margin_lo", "margin_hi", "planner", "planner_success",
           "gap_to_planner", "gap_lo", "gap_hi"]


def _ranked(group: pd.DataFrame) -> list[tuple[str, np.ndarray]]:
    """(method, per-seed scores) by decreasing mean success, ties in legend order."""
    per = [(m, g["success_rate"].to_numpy()) for m, g in group.groupby("method")]
    return sorted(per, key=lambda t: (-float(np.nanmean(t[1])), label_order(method_label(t[0])), t[0]))


def leaders_frame(evals: pd.DataFrame) -> pd.DataFrame:
    """One row per (N, p, learned execution mode) that has a learned method; see the module
    docstring. Runner-up and margin are empty (NaN) where one learned method ran; planner
    and gap where no planner ran at that configuration."""
    scores = seed_scores(evals)
    rows = []
    modes = [m for m in execution_order(scores["execution"]) if m != PLANNER]
    for (n, p), cfg in scores.groupby(["n_robots", "loss_p"]):
        planners = _ranked(cfg[cfg["execution"] == PLANNER])
        for mode in modes:
            ranked = _ranked(cfg[cfg["execution"] == mode])
            if not ranked:
                continue
            (lead, a), rest = ranked[0], ranked[1:]
            row = {"n_robots": int(n), "loss_p": float(p), "execution": mode, "methods": len(ranked),
                   "leader": lead, "leader_success": float(np.nanmean(a)), "runner_up": "", "planner": ""}
            if rest:
                second, b = rest[0]
                margin, lo, hi = _diff(a, b)
                row.update(runner_up=second, runner_up_success=float(np.nanmean(b)),
                           margin=margin, margin_lo=lo, margin_hi=hi)
            if planners:
                best, c = planners[0]
                gap, lo, hi = _diff(a, c)
                row.update(planner=best, planner_success=float(np.nanmean(c)),
                           gap_to_planner=gap, gap_lo=lo, gap_hi=hi)
            rows.append(row)
    return pd.DataFrame(rows, columns=COLUMNS)  # what a row leaves out is NaN


def _diff(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float]:
    """mean(a) - mean(b) with its 95% Welch t CI over seeds, cut at [-1, 1] (a difference
    of two rates; ``cut_interval``)."""
    t = t_test([a, b], [1.0, -1.0])
    return (float(np.nanmean(a) - np.nanmean(b)), *cut_interval(t.lo, t.hi, floor=-1.0))


def _pp(v: float) -> str:
    return f"{100 * v:+.1f}"


def _cell(r: pd.Series, full: bool) -> str:
    """``Leader 84.3% > Runner-up 48.5% (+35.8 pp [+6.1, +65.5])``, or without the rates and
    the interval (``full=False``: the index page's narrow cells); ``Leader 61.4% (only
    learned method)``."""
    rate = (lambda v: f" {100 * v:.1f}%") if full else (lambda v: "")
    head = f"{method_label(r['leader'])}{rate(r['leader_success'])}"
    if not r["runner_up"]:
        return f"{head} (only learned method)"
    separated = np.isfinite(r["margin_lo"]) and r["margin_lo"] > 0
    ci = f" [{_pp(r['margin_lo'])}, {_pp(r['margin_hi'])}]" if full and np.isfinite(r["margin_lo"]) else ""
    return (f"{head} {'>' if separated else '≈'} {method_label(r['runner_up'])}{rate(r['runner_up_success'])} "
            f"({_pp(r['margin'])} pp{ci})")


def leaders_display(frame: pd.DataFrame, full: bool = False) -> pd.DataFrame:
    """The matrices as one table: a row per (execution mode, N), a column per p (``full``:
    with the rates and the margin's CI, as leaders.md; else the leader, the runner-up and
    the margin, for the index page)."""
    if frame.empty:
        return pd.DataFrame()
    shown = frame.assign(text=frame.apply(_cell, axis=1, full=full), p=frame["loss_p"].map(lambda p: f"p = {fmt_p(p)}"))
    wide = shown.pivot_table(index=["execution", "n_robots"], columns="p", values="text", aggfunc="first").reset_index()
    order = {m: i for i, m in enumerate(execution_order(frame["execution"]))}
    wide = wide.assign(_m=wide["execution"].map(order)).sort_values(["_m", "n_robots"]).drop(columns="_m")
    ps = [f"p = {fmt_p(p)}" for p in sorted(frame["loss_p"].unique())]
    return wide[["execution", "n_robots", *ps]].rename(columns={"n_robots": "N"}).fillna("").reset_index(drop=True)


def _n(k: int, noun: str) -> str:
    """``1 configuration``, ``2 configurations``."""
    return f"{k} {noun}{'' if k == 1 else 's'}"


def _counts(part: pd.DataFrame) -> str:
    """``Decentralized leads 7 of 15 configurations with two or more learned methods (5 by a
    margin whose CI excludes 0); ...; 3 configurations have one learned method``."""
    contested = part[part["runner_up"] != ""]
    out = []
    for m, g in sorted(contested.groupby("leader"), key=lambda t: (-len(t[1]), label_order(method_label(t[0])))):
        out.append(f"{method_label(m)} leads {len(g)} of {_n(len(contested), 'configuration')} with two or more "
                   f"learned methods ({int((g['margin_lo'] > 0).sum())} by a margin whose CI excludes 0)")
    if len(contested) < len(part):
        alone = len(part) - len(contested)
        out.append(f"{_n(alone, 'configuration')} {'has' if alone == 1 else 'have'} one learned method")
    return "; ".join(out)


def _planner_line(part: pd.DataFrame) -> str:
    """How far the leading learned method stays from the best planner, over the configurations."""
    have = part[part["planner"] != ""]
    if have.empty:
        return "no planner ran at these configurations."
    labels = ", ".join(sorted({method_label(m) for m in have["planner"]}))
    below, above = int((have["gap_hi"] < 0).sum()), int((have["gap_lo"] > 0).sum())

    def span(values: pd.Series, fmt) -> str:  # "a" or "a to b"
        lo, hi = fmt(values.min()), fmt(values.max())
        return lo if lo == hi else f"{lo} to {hi}"

    return (f"the leading learned method's success minus the best planner's ({labels}: "
            f"{span(have['planner_success'], lambda v: f'{100 * v:.1f}%')}) is "
            f"{span(have['gap_to_planner'], _pp)} pp; its CI lies below 0 at {below} and above 0 at {above} "
            f"of the {_n(len(have), 'configuration')} with a planner.")


def leaders_markdown(frame: pd.DataFrame) -> str:
    """The page ``leaders.md``: per learned execution mode, the N x p matrix of leaders, how
    many configurations each method leads, and the distance to the planners."""
    lines = ["# Who leads where", "",
             "Per configuration (team size N, loss probability p) and learned execution mode: the learned method "
             "with the highest mean success over seeds, then the runner-up, and the leader's margin in percentage "
             "points [95% Welch t CI over seeds]. \">\" where that interval excludes 0, \"≈\" where it does not. "
             "The leader is picked by its mean and the intervals are pointwise (not corrected for the number of "
             "configurations; where no method is better, \">\" appears at under 5% of them, simulated): this "
             "describes the run, the calibrated verdicts are in claims.md. Planners are "
             "listed apart, as a reference (PIBT plans with full information).", ""]
    if frame.empty:
        return "\n".join(lines + ["No learned method was evaluated yet.", ""])
    display = leaders_display(frame, full=True)
    ps = [c for c in display.columns if c.startswith("p = ")]
    for mode in execution_order(frame["execution"]):
        part = frame[frame["execution"] == mode]
        rows = display[display["execution"] == mode]
        lines += [f"## {mode}", "", "| N | " + " | ".join(ps) + " |", "|---|" + "---|" * len(ps)]
        lines += [f"| {r['N']} | " + " | ".join(r[p] or "—" for p in ps) + " |" for _, r in rows.iterrows()]
        lines += ["", f"{_counts(part)}. Against the planners: {_planner_line(part)}", ""]
    return "\n".join(lines)
