"""Study figures: optimization history, the L x |R_z| landscape, parameter importances.

Pure builders take the trials frame (studies/export.py ``trials_frame``) or the stored
importances and return a ``Built`` figure (reports/plotting.py); only
``build_study_report`` writes files: ``<study_dir>/report/study_{history,landscape,
importances}.{png,pdf}`` and ``study.md``. It reads ``trials.parquet`` and
``importances.json`` alone, so ``bench report`` can include a study from any storage.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from envs.errors import BenchError
from reports.plotting import Built, new_figure, paper_style, placeholder
from studies.export import IMPORTANCES_FILE, TRIALS_FILE, read_trials
from studies.space import REF_SIZES, SEARCH_RADII

REPORT_DIR = "report"
PARAM_LABELS = {"ref_size": r"$|\mathcal{R}_z|$ (reference-space size)", "search_radius": r"$L$ (search radius)",
                "c_max": r"$C_{\max}$ (candidate budget)"}


def history_figure(trials: pd.DataFrame) -> Built:
    """Objective per trial number (complete and pruned) and the best value so far."""
    with paper_style():
        fig = new_figure(2.4)
        ax = fig.add_subplot()
        done = trials[trials["state"].isin(["COMPLETE", "PRUNED"])].sort_values("number")
        if done.empty:
            placeholder(ax, "no finished trial yet")
            return Built(fig, ["no finished trial"])
        for state, marker, color in (("COMPLETE", "o", "C0"), ("PRUNED", "x", "C3")):
            part = done[done["state"] == state]
            ax.scatter(part["number"], part["value"], marker=marker, color=color,
                       label=f"{state.lower()} ({len(part)})", zorder=3)
        comp = done[done["state"] == "COMPLETE"]
        if not comp.empty:
            best = comp["value"].cummax()
            ax.step(comp["number"], best, where="post", color="0.2", label="best so far")
        ax.set_xlabel("trial number")
        ax.set_ylabel("objective (success rate\n+ 1e-3 x return tie-break)")
        ax.set_title("Optimization history")
        ax.legend(loc="lower right")
        notes = ["pruned trials show their last intermediate value"] if (done["state"] == "PRUNED").any() else []
        return Built(fig, notes)


def landscape_table(trials: pd.DataFrame, value: str = "success_rate") -> tuple[pd.DataFrame, pd.DataFrame]:
    """(mean, count) tables of complete trials: rows L (search_radius), columns |R_z|.

    Every value of the default space appears, so missing configurations show as NaN.
    """
    comp = trials[trials["state"] == "COMPLETE"]
    rows = sorted(set(SEARCH_RADII) | set(comp["search_radius"].dropna().astype(int)))
    cols = sorted(set(REF_SIZES) | set(comp["ref_size"].dropna().astype(int)))
    grouped = comp.groupby(["search_radius", "ref_size"])[value]
    mean = grouped.mean().unstack().reindex(index=rows, columns=cols).astype(float)
    count = grouped.size().unstack().reindex(index=rows, columns=cols).fillna(0).astype(int)
    return mean, count


def landscape_figure(trials: pd.DataFrame) -> Built:
    """Heatmap of the mean evaluation success rate over L x |R_z| (complete trials)."""
    import seaborn as sns

    mean, count = landscape_table(trials)
    notes = []
    if "c_max" in trials and trials["c_max"].notna().any():
        notes.append("averaged over the searched C_max values")
    with paper_style():
        fig = new_figure(2.4)
        ax = fig.add_subplot()
        if count.to_numpy().sum() == 0:
            placeholder(ax, "no complete trial yet")
            return Built(fig, ["no complete trial"])
        labels = np.array([[f"{m:.2f}\n(n={c})" if c else "" for m, c in zip(mr, cr, strict=False)]
                           for mr, cr in zip(mean.to_numpy(), count.to_numpy(), strict=False)])
        sns.heatmap(mean, ax=ax, annot=labels, fmt="", vmin=0.0, vmax=1.0, cmap="viridis",
                    cbar_kws={"label": "success rate"}, annot_kws={"fontsize": 5},
                    linewidths=0.4, linecolor="white")
        ax.set_xlabel(PARAM_LABELS["ref_size"])
        ax.set_ylabel(PARAM_LABELS["search_radius"])
        ax.set_title("Landscape: mean evaluation success rate")
        missing = int((count.to_numpy() == 0).sum())
        if missing:
            notes.append(f"{missing} of {count.size} configurations not evaluated (blank)")
        return Built(fig, notes)


def importance_figure(imp: dict[str, Any]) -> Built:
    """Horizontal bars of Optuna's parameter importances, or why there are none."""
    with paper_style():
        fig = new_figure(1.6)
        ax = fig.add_subplot()
        values = imp.get("importances") or {}
        if not values:
            reason = imp.get("reason") or "no importances"
            placeholder(ax, reason)
            return Built(fig, [reason])
        names = sorted(values, key=values.get)
        ax.barh([PARAM_LABELS.get(n, n) for n in names], [values[n] for n in names], color="C0")
        ax.set_xlabel("importance (fANOVA, share of objective variance)")
        ax.set_xlim(0, 1)
        ax.set_title("Parameter importances")
        return Built(fig, [])


def summary_markdown(trials: pd.DataFrame, imp: dict[str, Any]) -> str:
    """A short page: counts per state, the best complete trial, importances."""
    counts = trials["state"].value_counts().to_dict()
    name = trials["study"].iloc[0] if len(trials) else "?"
    lines = [f"# Study {name}", "",
             "trials: " + ", ".join(f"{k.lower()} {v}" for k, v in sorted(counts.items())), ""]
    comp = trials[trials["state"] == "COMPLETE"]
    if not comp.empty:
        best = comp.loc[comp["value"].idxmax()]
        params = [c for c in ("ref_size", "search_radius", "c_max") if c in comp and pd.notna(best.get(c))]
        lines += [f"best: trial {int(best['number'])} " +
                  ", ".join(f"{p}={int(best[p])}" for p in params) +
                  f" (success rate {best['success_rate']:.3f}, team return {best['team_return']:.2f})", ""]
    values = imp.get("importances") or {}
    lines.append("importances: " + (", ".join(f"{k} {v:.2f}" for k, v in values.items())
                                    if values else str(imp.get("reason"))))
    return "\n".join(lines) + "\n"


def build_study_report(study_dir: Path | str) -> list[Path]:
    """Write the study's figures (PNG + PDF) and ``study.md`` into ``study_dir/report``."""
    from reports.build import save_figure, write_text

    study_dir = Path(study_dir)
    path = study_dir / TRIALS_FILE
    if not path.exists():
        raise BenchError(f"no {TRIALS_FILE} in {str(study_dir)!r}; run `bench tune` first")
    trials = read_trials(path)
    imp_path = study_dir / IMPORTANCES_FILE
    imp = json.loads(imp_path.read_text()) if imp_path.exists() else {"reason": "not computed"}
    out_dir = study_dir / REPORT_DIR
    out: list[Path] = []
    for stem, built in (("study_history", history_figure(trials)),
                        ("study_landscape", landscape_figure(trials)),
                        ("study_importances", importance_figure(imp))):
        out += save_figure(built.fig, out_dir / stem)
    out.append(write_text(out_dir / "study.md", summary_markdown(trials, imp)))
    return out
