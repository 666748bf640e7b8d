"""Table I: safety filter of the hierarchical method at p = 0.2 (tab:safety).

One row per team size (the paper's 40, 60, 80, 90, 100 plus any other N the run has):
collision rate, correction rate and mean candidates (Algorithm 1, eq:safety_conditions)
as in the paper, plus the predictor error (eq:gru_pred_loss on lost messages) and the
fallback rate (group-steps that fell back to the joint Wait). Each value is the mean
over seeds of the per-seed mean over evaluation episodes, with a 95% Student t CI over
seeds (a bootstrap over evaluation episodes when there is one seed). The paper's values sit beside
ours; team sizes the run lacks are marked "not run". One table per execution mode
(argmax, sample, sample@T: the filter corrects what the policy proposes, so the mode
changes every column); the paper's values are for its argmax execution.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from paper.settings import PAPER_TABLE1, PAPER_TABLE1_P
from reports.data.store import execution_order, fmt_p, fmt_pct, select
from reports.tables.summary import metric_estimate

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
    p = PAPER_TABLE1_P if (not ps or any(np.isclose(PAPER_TABLE1_P, q) for q in ps)) else ps[0]
    if ps and not np.isclose(p, PAPER_TABLE1_P):
        notes.append(f"the run has no hierarchical cells at p = {fmt_p(PAPER_TABLE1_P)}; showing p = {fmt_p(p)}")
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
    rec["safety_filter"] = bool(rows["safety_filter"].any()) if len(rows) else True
    rec["paper_collision_rate"] = paper[0] if paper else np.nan
    rec["paper_correction_rate"] = paper[1] if paper else np.nan
    rec["paper_mean_candidates"] = paper[2] if paper else np.nan
    return rec


NO_FILTER = {"correction_rate", "mean_candidates"}  # undefined without a safety filter: "n/a"
MISSING = "--"


def _has_filter(rec: pd.Series) -> bool:
    return bool(rec.get("safety_filter", True))


def _num(m: str, v: float, unit: str) -> str:
    """A rate in percent (with ``unit`` after it), anything else with two decimals.
    Collision rates get three significant digits (the paper reports 0.00%: 0.0008% must
    not print as 0.00% beside it), as does any other rate two decimals would hide."""
    return fmt_pct(v, 2, always_sig=m == "collision_rate") + unit if m in RATES else f"{v:.2f}"


def _value(rec: pd.Series, m: str, v: float, unit: str = "%") -> str:
    if m in NO_FILTER and not _has_filter(rec):
        return "n/a"
    if not np.isfinite(v):
        return MISSING
    return _num(m, v, unit)


def _ci(rec: pd.Series, m: str, unit: str = "%") -> str:
    lo, hi = rec[f"{m}_lo"], rec[f"{m}_hi"]
    if (m in NO_FILTER and not _has_filter(rec)) or not (np.isfinite(lo) and np.isfinite(hi)):
        return ""
    return f"[{_num(m, lo, '')}, {_num(m, hi, unit)}]"


def _cell(rec: pd.Series, m: str) -> str:
    """Mean and CI in one cell (Markdown)."""
    ci = _ci(rec, m, "")
    return _value(rec, m, rec[m]) + (f" {ci}" if ci else "")


def _paper(rec: pd.Series, key: str, unit: str = "%") -> str:
    v = rec[f"paper_{key}"]
    return MISSING if not np.isfinite(v) else _num(key, v, unit)


HEAD = ["N", "Collision rate", "(paper)", "Correction rate", "(paper)", "Mean candidates",
        "(paper)", "Predictor error", "Fallback rate", "Seeds", "Episodes"]
DISPLAY_HEAD = ["N", "row", "Coll. (%)", "Corr. (%)", "Cand.", "Pred. err.", "Fallb. (%)", "Seeds/eps."]
TABLE1_KEYS = ("collision_rate", "correction_rate", "mean_candidates")


def _row_cells(rec: pd.Series) -> list[str]:
    if rec["status"] == "not run":
        return [str(rec["n_robots"]), "not run", _paper(rec, "collision_rate"), MISSING,
                _paper(rec, "correction_rate"), MISSING, _paper(rec, "mean_candidates"),
                MISSING, MISSING, "0", "0"]
    return [str(rec["n_robots"]), _cell(rec, "collision_rate"), _paper(rec, "collision_rate"),
            _cell(rec, "correction_rate"), _paper(rec, "correction_rate"),
            _cell(rec, "mean_candidates"), _paper(rec, "mean_candidates"),
            _cell(rec, "predictor_error"), _cell(rec, "fallback_rate"),
            str(rec["seeds"]), str(rec["episodes"])]


def _modes(frame: pd.DataFrame) -> list[str]:
    return list(dict.fromkeys(frame["execution"])) if len(frame) else ["argmax"]


def table1_display(frame: pd.DataFrame, mode: str) -> pd.DataFrame:
    """Table I of one execution mode as display strings, narrow enough for a page: per team
    size a row "ours" (means), a row "95% CI" (when there is one) and a row "paper" (the
    paper's Table I, when it has that N). Correction rate and mean candidates are "n/a"
    for cells without a safety filter; missing values are "--"."""
    out = []
    for _, rec in frame[frame["execution"] == mode].iterrows():
        n = str(rec["n_robots"])
        if rec["status"] == "not run":
            out.append([n, "ours", "not run", *[MISSING] * 4, "0/0"])
        else:
            out.append([n, "ours", *[_value(rec, m, rec[m], "") for m in METRICS],
                        f"{rec['seeds']}/{rec['episodes']}"])
            cis = [_ci(rec, m, "") for m in METRICS]
            if any(cis):
                out.append(["", "95% CI", *[c or MISSING for c in cis], ""])
        if np.isfinite(rec["paper_collision_rate"]):
            out.append(["", "paper", *[_paper(rec, k, "") for k in TABLE1_KEYS], MISSING, MISSING, ""])
    return pd.DataFrame(out, columns=DISPLAY_HEAD)


def table1_caption(frame: pd.DataFrame, mode: str) -> str:
    """The caption of Table I in one execution mode (plain text)."""
    p = fmt_p(frame["loss_p"].iloc[0]) if len(frame) else fmt_p(PAPER_TABLE1_P)
    return (f"Safety filter performance of the hierarchical method under p = {p}, {mode} execution: "
            "mean over seeds of per-seed means over evaluation episodes (ours), a 95% CI (Student t over "
            "seeds, or bootstrap over episodes with one seed) and the paper's Table I (argmax "
            "execution). Coll.: collision rate; Corr.: correction rate; Cand.: mean candidates; "
            "Pred. err.: mean squared error of predicted messages on lost links; Fallb.: group-steps "
            "that fell back to the joint Wait; Seeds/eps.: seeds and evaluation episodes; n/a: no "
            "safety filter.")


def table1_markdown(frame: pd.DataFrame, notes: list[str]) -> str:
    p = fmt_p(frame["loss_p"].iloc[0]) if len(frame) else fmt_p(PAPER_TABLE1_P)
    lines = [f"# Table I: safety filter performance (hierarchical, p = {p})", "",
             "Mean over seeds [95% CI: Student t over seeds, or bootstrap over evaluation episodes "
             "when a configuration has one seed]; \"(paper)\" is the paper's Table I (argmax execution). "
             "Predictor error: mean squared error of predicted messages on lost links "
             "(eq:gru_pred_loss); fallback rate: group-steps that fell back to the joint Wait "
             "(Algorithm 1); n/a: cells without a safety filter. One table per execution mode, all "
             "on the same evaluation scenarios."]
    for mode in _modes(frame):
        lines += ["", f"## Execution: {mode}", "",
                  "| " + " | ".join(HEAD) + " |", "|" + "---|" * len(HEAD)]
        for _, rec in frame[frame["execution"] == mode].iterrows():
            lines.append("| " + " | ".join(_row_cells(rec)) + " |")
    if notes:
        lines += [""] + [f"- {n}" for n in notes]
    return "\n".join(lines) + "\n"


_LATEX_SPECIAL = str.maketrans({c: "\\" + c for c in "%&_#${}"} | {"~": r"\textasciitilde{}",
                                                                   "^": r"\textasciicircum{}",
                                                                   "\\": r"\textbackslash{}"})


def _latex_text(text: str) -> str:
    """Plain text for a LaTeX caption (the cells are escaped by pandas' Styler)."""
    return text.translate(_LATEX_SPECIAL)


def table1_latex(frame: pd.DataFrame) -> str:
    """One LaTeX ``table*`` per execution mode (label tab:safety_reproduced_<mode>), written
    by pandas' ``Styler.to_latex`` (cells escaped by pandas; needs booktabs)."""
    parts = ["% Table I reproduced (bench report); needs \\usepackage{booktabs}", ""]
    for mode in _modes(frame):
        label = "".join(c if c.isalnum() else "_" for c in mode)
        disp = table1_display(frame, mode).rename(columns={"row": ""})
        styler = (disp.style.hide(axis="index").format(escape="latex")
                  .format_index(escape="latex", axis=1))
        tex = styler.to_latex(
            environment="table*", position="t", position_float="centering", hrules=True,
            column_format="ll" + "r" * (disp.shape[1] - 2), label=f"tab:safety_reproduced_{label}",
            caption=_latex_text(table1_caption(frame, mode)))
        parts.append(tex.replace("\\begin{tabular}", "\\small\n\\begin{tabular}", 1))
    return "\n".join(parts)
