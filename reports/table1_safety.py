"""Table I: safety filter of the hierarchical method at p = 0.2 (tab:safety).

One row per team size (the paper's 40, 60, 80, 90, 100 plus any other N the run has):
collision rate, correction rate and mean candidates (Algorithm 1, eq:safety_conditions)
as in the paper, plus the predictor error (eq:gru_pred_loss on lost messages) and the
fallback rate (group-steps that fell back to the joint Wait). Each value is the mean
over seeds of the per-seed mean over evaluation episodes, with a 95% bootstrap CI over
seeds (over evaluation episodes when there is one seed). The paper's values sit beside
ours; team sizes the run lacks are marked "not run". One table per execution mode
(argmax, sample, sample@T: the filter corrects what the policy proposes, so the mode
changes every column); the paper's values are for its argmax execution.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from reports.store import execution_order, fmt_p, select
from reports.summary import metric_estimate

PAPER_P = 0.2
# tab:safety: N -> (collision rate, correction rate, mean candidates); rates as fractions.
PAPER_TABLE1 = {
    40: (0.0, 0.0345, 3.79), 60: (0.0, 0.0548, 16.44), 80: (0.0, 0.0790, 24.15),
    90: (0.0, 0.0654, 35.63), 100: (0.0, 0.0734, 24.68),
}
METRICS = ("collision_rate", "correction_rate", "mean_candidates", "predictor_error", "fallback_rate")
RATES = {"collision_rate", "correction_rate", "fallback_rate"}
LABELS = {"collision_rate": "Collision rate", "correction_rate": "Correction rate",
          "mean_candidates": "Mean candidates", "predictor_error": "Predictor error",
          "fallback_rate": "Fallback rate"}


def table1_frame(evals: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """Table I as numbers (rates as fractions), one block of rows per execution mode
    (column ``execution``), and notes about what the run lacks."""
    notes: list[str] = []
    hier = select(evals, "hierarchical")
    ps = sorted(set(hier["loss_p"].dropna().astype(float)))
    p = PAPER_P if (not ps or any(np.isclose(PAPER_P, q) for q in ps)) else ps[0]
    if ps and not np.isclose(p, PAPER_P):
        notes.append(f"the run has no hierarchical cells at p = {fmt_p(PAPER_P)}; showing p = {fmt_p(p)}")
    at_p = select(hier, loss_p=p)
    ns = sorted(set(int(n) for n in at_p["n_robots"]) | set(PAPER_TABLE1))
    missing = [n for n in PAPER_TABLE1 if n not in set(at_p["n_robots"])]
    if missing:
        notes.append("team sizes of the paper's Table I the run lacks: " + ", ".join(map(str, missing)))
    out = []
    for mode in execution_order(at_p["execution"]) or ["argmax"]:
        by_mode = at_p[at_p["execution"] == mode]
        out += [_table1_row(by_mode[by_mode["n_robots"] == n], n, p, mode) for n in ns]
    return pd.DataFrame(out), notes


def _table1_row(rows: pd.DataFrame, n: int, p: float, mode: str) -> dict[str, object]:
    """Table I's row of team size ``n`` in execution mode ``mode`` (``rows``: its eval rows)."""
    rec: dict[str, object] = {"execution": mode, "n_robots": n, "loss_p": p,
                              "seeds": rows["cell_id"].nunique(),
                              "episodes": len(rows), "status": "ok" if len(rows) else "not run"}
    if len(rows) and not rows["safety_filter"].all():
        rec["status"] = "filter off in some cells"
    for m in METRICS:
        mean, lo, hi, unit = metric_estimate(rows, m) if len(rows) else (np.nan,) * 3 + ("-",)
        rec[m], rec[f"{m}_lo"], rec[f"{m}_hi"] = mean, lo, hi
        rec["ci_over"] = unit if len(rows) else "-"
    paper = PAPER_TABLE1.get(n)
    rec["paper_collision_rate"] = paper[0] if paper else np.nan
    rec["paper_correction_rate"] = paper[1] if paper else np.nan
    rec["paper_mean_candidates"] = paper[2] if paper else np.nan
    return rec


def _cell(rec: pd.Series, m: str, latex: bool = False) -> str:
    v = rec[m]
    if not np.isfinite(v):
        return "--" if latex else "—"
    lo, hi = rec[f"{m}_lo"], rec[f"{m}_hi"]
    pct = r"\%" if latex else "%"
    if m in RATES:
        main = f"{100 * v:.2f}{pct}"
        ci = f"[{100 * lo:.2f}, {100 * hi:.2f}]"
    else:
        main, ci = f"{v:.2f}", f"[{lo:.2f}, {hi:.2f}]"
    return f"{main} {ci}" if np.isfinite(lo) else main


def _paper(rec: pd.Series, key: str, latex: bool = False) -> str:
    v = rec[f"paper_{key}"]
    if not np.isfinite(v):
        return "--" if latex else "—"
    return f"{100 * v:.2f}" + (r"\%" if latex else "%") if key != "mean_candidates" else f"{v:.2f}"


HEAD = ["N", "Collision rate", "(paper)", "Correction rate", "(paper)", "Mean candidates",
        "(paper)", "Predictor error", "Fallback rate", "Seeds", "Episodes"]


def _row_cells(rec: pd.Series, latex: bool) -> list[str]:
    if rec["status"] == "not run":
        dash = "--" if latex else "—"
        return [str(rec["n_robots"]), "not run", _paper(rec, "collision_rate", latex), dash,
                _paper(rec, "correction_rate", latex), dash, _paper(rec, "mean_candidates", latex),
                dash, dash, "0", "0"]
    return [str(rec["n_robots"]), _cell(rec, "collision_rate", latex), _paper(rec, "collision_rate", latex),
            _cell(rec, "correction_rate", latex), _paper(rec, "correction_rate", latex),
            _cell(rec, "mean_candidates", latex), _paper(rec, "mean_candidates", latex),
            _cell(rec, "predictor_error", latex), _cell(rec, "fallback_rate", latex),
            str(rec["seeds"]), str(rec["episodes"])]


def _modes(frame: pd.DataFrame) -> list[str]:
    return list(dict.fromkeys(frame["execution"])) if len(frame) else ["argmax"]


def table1_markdown(frame: pd.DataFrame, notes: list[str]) -> str:
    p = fmt_p(frame["loss_p"].iloc[0]) if len(frame) else fmt_p(PAPER_P)
    lines = [f"# Table I: safety filter performance (hierarchical, p = {p})", "",
             "Mean over seeds [95% bootstrap CI over seeds, or over evaluation episodes when a "
             "configuration has one seed]; \"(paper)\" is the paper's Table I (argmax execution). "
             "Predictor error: mean squared error of predicted messages on lost links "
             "(eq:gru_pred_loss); fallback rate: group-steps that fell back to the joint Wait "
             "(Algorithm 1). One table per execution mode, all on the same evaluation scenarios."]
    for mode in _modes(frame):
        lines += ["", f"## Execution: {mode}", "",
                  "| " + " | ".join(HEAD) + " |", "|" + "---|" * len(HEAD)]
        for _, rec in frame[frame["execution"] == mode].iterrows():
            lines.append("| " + " | ".join(_row_cells(rec, False)) + " |")
    if notes:
        lines += [""] + [f"- {n}" for n in notes]
    return "\n".join(lines) + "\n"


def table1_latex(frame: pd.DataFrame) -> str:
    """One LaTeX table per execution mode (label tab:safety_reproduced_<mode>)."""
    p = fmt_p(frame["loss_p"].iloc[0]) if len(frame) else fmt_p(PAPER_P)
    lines: list[str] = []
    for mode in _modes(frame):
        label = "".join(c if c.isalnum() else "_" for c in mode)
        lines += [r"\begin{table}[t]", r"\centering",
                  rf"\caption{{Safety filter performance under $p={p}$, {mode} execution (ours, with "
                  r"the paper's values in parentheses columns; 95\% bootstrap CI in brackets).}}",
                  rf"\label{{tab:safety_reproduced_{label}}}", r"\small", r"\setlength{\tabcolsep}{3pt}",
                  r"\begin{tabular}{c|cc|cc|cc|cc|cc}", r"\hline",
                  " & ".join(rf"\textbf{{{h}}}" for h in HEAD) + r" \\", r"\hline"]
        for _, rec in frame[frame["execution"] == mode].iterrows():
            lines.append(" & ".join(_row_cells(rec, True)) + r" \\")
        lines += [r"\hline", r"\end{tabular}", r"\end{table}", ""]
    return "\n".join(lines)
