"""Study figures: optimization history, the landscape (L x |R_z| for the paper's study, the
objective per parameter value for any other), intermediate-value curves, parameter
importances.

Pure builders take the trials frame (studies/export.py ``trials_frame``) or the stored
importances and return a ``Built`` figure (reports/figures/plotting.py); only
``build_study_report`` writes files: ``<study_dir>/report/study_{history,landscape,curves,
importances}.{png,pdf}``, ``study.md`` and ``study.html`` (studies/report_page.py). It reads
``trials.parquet``, ``importances.json`` and ``study.json`` alone (names:
bench/store/study_files.py); ``bench report`` of the run a study was launched for copies
the built files into the run's report.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from bench.store.study_files import (
    CONFIG_FILE,
    IMPORTANCES_FILE,
    REPORT_DIR,
    REPORT_FIGURES,
    REPORT_PAGES,
    TRIALS_FILE,
)
from envs.errors import BenchError
from reports.figures.plotting import FONT_PT, Built, new_figure, paper_style, placeholder
from studies.export import read_trials
from studies.space import REF_SIZES, SEARCH_RADII, plain
from studies.trial_columns import param_columns

HEATMAP_SPACE = {"ref_size", "search_radius", "c_max"}  # the paper's study (SPEC 6), drawn as L x |R_z|
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


def landscape_table(trials: pd.DataFrame, value: str = "success_rate",
                    ) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """(mean over complete trials, complete count, pruned count): rows L (search_radius),
    columns |R_z|. Every value of the default space appears, so configurations never run
    show as NaN with both counts 0, and a configuration whose trials were all pruned as NaN
    with a pruned count."""
    done = trials[trials["state"].isin(["COMPLETE", "PRUNED"])].dropna(subset=["search_radius", "ref_size"])
    rows = sorted(set(SEARCH_RADII) | set(done["search_radius"].astype(int)))
    cols = sorted(set(REF_SIZES) | set(done["ref_size"].astype(int)))
    comp = done[done["state"] == "COMPLETE"]
    mean = comp.groupby(["search_radius", "ref_size"])[value].mean().unstack()
    mean = mean.reindex(index=rows, columns=cols).astype(float)

    def counts(part: pd.DataFrame) -> pd.DataFrame:
        table = part.groupby(["search_radius", "ref_size"]).size().unstack()
        return table.reindex(index=rows, columns=cols).fillna(0).astype(int)

    return mean, counts(comp), counts(done[done["state"] == "PRUNED"])


def is_paper_space(trials: pd.DataFrame) -> bool:
    """Whether the study searches L x |R_z| (with C_max at most): the paper's study, whose
    landscape is the L x |R_z| heatmap; any other study's is the per-parameter slice."""
    names = set(param_columns(trials))
    return {"search_radius", "ref_size"} <= names <= HEATMAP_SPACE


def landscape_figure(trials: pd.DataFrame) -> Built:
    """The study's landscape. The paper's study (L x |R_z|, C_max at most): a heatmap of the
    mean evaluation success rate over L x |R_z|; every cell says how many trials completed
    and were pruned, and a cell whose trials were all pruned is hatched (evaluated and
    stopped, not missing). Any other study: ``slice_figure``."""
    import seaborn as sns
    from matplotlib.patches import Patch, Rectangle

    if not is_paper_space(trials):  # a study of other parameters: one panel per parameter
        return slice_figure(trials)
    mean, n_comp, n_pruned = landscape_table(trials)
    notes = []
    if "c_max" in trials and trials["c_max"].notna().any():
        notes.append("averaged over the searched C_max values")
    with paper_style():
        fig = new_figure(2.6)
        ax = fig.add_subplot()
        if (n_comp.to_numpy() + n_pruned.to_numpy()).sum() == 0:
            placeholder(ax, "no finished trial yet")
            return Built(fig, ["no finished trial"])
        labels = np.empty(mean.shape, dtype=object)
        for (i, j), m in np.ndenumerate(mean.to_numpy()):
            c, p = int(n_comp.iat[i, j]), int(n_pruned.iat[i, j])
            counts = f"{c} ok" + (f", {p} pr" if p else "")
            labels[i, j] = (f"{m:.2f}\n{counts}" if c else (f"pruned\n{p} pr" if p else "not run"))
        sns.heatmap(mean, ax=ax, vmin=0.0, vmax=1.0, cmap="viridis",
                    cbar_kws={"label": "mean success rate (complete trials)"},
                    linewidths=0.4, linecolor="white")
        ax.set_facecolor("0.93")  # NaN cells: light grey behind the annotations
        for (i, j), text in np.ndenumerate(labels):  # seaborn leaves NaN cells unlabelled
            m = mean.iat[i, j]
            dark = pd.notna(m) and m < 0.6
            ax.text(j + 0.5, i + 0.5, text, ha="center", va="center", fontsize=4.5,
                    color="white" if dark else "black")
        for (i, j), p in np.ndenumerate(n_pruned.to_numpy()):
            if p and not n_comp.iat[i, j]:
                ax.add_patch(Rectangle((j, i), 1, 1, fill=False, hatch="///", edgecolor="C3", linewidth=0))
        ax.set_xlabel(PARAM_LABELS["ref_size"])
        ax.set_ylabel(PARAM_LABELS["search_radius"])
        ax.grid(False)
        ax.set_title("Mean success rate (ok = complete, pr = pruned trials)")
        ax.legend(handles=[Patch(facecolor="0.93", edgecolor="C3", hatch="///", label="all trials pruned"),
                           Patch(facecolor="0.93", label="not run")],
                  loc="upper left", bbox_to_anchor=(0.0, -0.22), ncols=2, frameon=False)
        all_pruned = int(((n_pruned.to_numpy() > 0) & (n_comp.to_numpy() == 0)).sum())
        missing = int(((n_pruned.to_numpy() == 0) & (n_comp.to_numpy() == 0)).sum())
        if all_pruned:
            notes.append(f"{all_pruned} configuration(s) evaluated but every trial pruned (hatched)")
        if missing:
            notes.append(f"{missing} of {mean.size} configurations not run")
        return Built(fig, notes)


def slice_table(trials: pd.DataFrame) -> pd.DataFrame:
    """One row per searched parameter and value: ``parameter``, ``value``, the mean
    objective of its complete trials (``mean``, NaN if none), and its ``complete`` and
    ``pruned`` trial counts (failed and running trials count nowhere)."""
    done = trials[trials["state"].isin(["COMPLETE", "PRUNED"])]
    rows = []
    for name in param_columns(trials):
        for value, part in done.dropna(subset=[name]).groupby(name):  # sorted by value
            comp = part[part["state"] == "COMPLETE"]
            rows.append({"parameter": name, "value": plain(value),
                         "mean": float(comp["value"].mean()),  # NaN without a complete trial
                         "complete": len(comp), "pruned": int((part["state"] == "PRUNED").sum())})
    return pd.DataFrame(rows, columns=["parameter", "value", "mean", "complete", "pruned"])


def slice_figure(trials: pd.DataFrame) -> Built:
    """One panel per searched parameter: the objective of every finished trial against the
    parameter's value (complete trials as dots, pruned ones as red crosses at their last
    intermediate value) and the mean of the complete trials per value (a black bar). With
    many parameters a heatmap of two would average over all the others; this shows each
    marginal with its spread."""
    table = slice_table(trials)
    names = list(dict.fromkeys(table["parameter"]))
    ncols = min(3, max(1, len(names)))
    nrows = max(1, -(-len(names) // ncols))
    with paper_style():
        fig = new_figure(1.25 * nrows + 0.5)
        if not names:
            placeholder(fig.add_subplot(), "no finished trial yet")
            return Built(fig, ["no finished trial"])
        axes = fig.subplots(nrows, ncols, sharey=True, squeeze=False).ravel()
        done = trials[trials["state"].isin(["COMPLETE", "PRUNED"])]
        for ax, name in zip(axes, names, strict=False):
            rows = table[table["parameter"] == name].reset_index(drop=True)
            values = done[name].map(plain)
            for x, row in rows.iterrows():
                part = done[values == row["value"]]
                for state, marker, color in (("COMPLETE", "o", "C0"), ("PRUNED", "x", "C3")):
                    ys = part.loc[part["state"] == state, "value"].to_numpy(float)
                    offsets = np.linspace(-0.18, 0.18, len(ys)) if len(ys) > 1 else np.zeros(len(ys))
                    ax.scatter(x + offsets, ys, marker=marker, color=color, s=6, linewidths=0.6,
                               alpha=0.7, zorder=3)
                if row["complete"]:
                    ax.plot([x - 0.3, x + 0.3], [row["mean"]] * 2, color="0.1", linewidth=1.2, zorder=4)
            ax.set_xticks(range(len(rows)), [_tick(v) for v in rows["value"]])
            ax.set_xlim(-0.6, len(rows) - 0.4)
            ax.set_title(PARAM_LABELS.get(name, name), fontsize=FONT_PT)
            ax.grid(axis="x", visible=False)
        for ax in axes[len(names):]:
            ax.set_visible(False)
        for ax in axes[::ncols]:
            ax.set_ylabel("objective")
        fig.suptitle("Objective per parameter value", fontsize=FONT_PT)
        pruned = int((done["state"] == "PRUNED").sum())
        notes = ["dots: complete trials; crosses: pruned trials; bar: mean of the complete trials",
                 f"each of the {len(names)} panels pools all values of the other parameters"]
        if pruned:
            notes.append(f"{pruned} pruned trial(s) shown at their last intermediate value")
        return Built(fig, notes)


def _tick(value: Any) -> str:
    """A compact tick label: 2e-4 rather than 0.0002."""
    if isinstance(value, float) and 0 < abs(value) < 0.01:
        mantissa, exponent = f"{value:.0e}".split("e")
        return f"{mantissa}e{int(exponent)}"
    return str(value)


def intermediate_curves(trials: pd.DataFrame) -> list[tuple[int, str, np.ndarray, np.ndarray]]:
    """(trial number, state, steps (K,), values (K,)) of every finished trial's reports."""
    out = []
    for _, row in trials[trials["state"].isin(["COMPLETE", "PRUNED"])].sort_values("number").iterrows():
        text = row.get("intermediate_json")
        raw = json.loads(text) if isinstance(text, str) else {}
        steps = np.array(sorted(int(k) for k in raw), dtype=int)
        values = np.array([raw[str(k)] for k in steps], dtype=float)
        out.append((int(row["number"]), str(row["state"]), steps, values))
    return out


def curves_figure(trials: pd.DataFrame, warmup: int | None = None) -> Built:
    """Intermediate objective value against training updates, one line per trial: complete
    trials blue, pruned ones red ending in a cross; a dashed line at the pruning warm-up."""
    with paper_style():
        fig = new_figure(2.4)
        ax = fig.add_subplot()
        curves = [c for c in intermediate_curves(trials) if len(c[2])]
        if not curves:
            placeholder(ax, "no intermediate values (multi-objective studies report none)")
            return Built(fig, ["no intermediate values"])
        for state, color in (("COMPLETE", "C0"), ("PRUNED", "C3")):
            part = [c for c in curves if c[1] == state]
            for k, (_, _, steps, values) in enumerate(part):
                ax.plot(steps, values, color=color, alpha=0.45, marker=".",
                        label=f"{state.lower()} ({len(part)})" if k == 0 else None)
                if state == "PRUNED":
                    ax.plot(steps[-1:], values[-1:], color=color, marker="x", linestyle="none")
        if warmup is not None:
            ax.axvline(warmup, color="0.3", linestyle="--", linewidth=0.8,
                       label=f"warm-up (pruning from update {warmup})")
        ax.set_xlabel("training updates")
        ax.set_ylabel("intermediate objective")
        ax.set_title("Intermediate values (what the pruner sees)")
        ax.legend(loc="best", framealpha=0.9)
        return Built(fig, [])


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
        names = sorted(values, key=lambda n: values[n])
        ax.barh([PARAM_LABELS.get(n, n) for n in names], [values[n] for n in names], color="C0")
        ax.set_xlabel("importance (fANOVA, share of objective variance)")
        ax.set_xlim(0, 1)
        ax.set_title("Parameter importances (rough: see the caveat)")
        return Built(fig, [imp["caveat"]] if imp.get("caveat") else [])


def build_study_report(study_dir: Path | str) -> list[Path]:
    """Write the study's figures (PNG + PDF), ``study.md`` and ``study.html`` into
    ``study_dir/report`` from ``trials.parquet`` (+ ``importances.json``, ``study.json``)."""
    from reports.writers import save_figure, write_text
    from studies.report_page import study_page

    study_dir = Path(study_dir)
    path = study_dir / TRIALS_FILE
    if not path.exists():
        raise BenchError(f"no {TRIALS_FILE} in {str(study_dir)!r}; run `bench tune` first")
    trials = read_trials(path)
    imp_path, cfg_path = study_dir / IMPORTANCES_FILE, study_dir / CONFIG_FILE
    imp = json.loads(imp_path.read_text()) if imp_path.exists() else {"reason": "not computed"}
    config = json.loads(cfg_path.read_text()) if cfg_path.exists() else {}
    out_dir = study_dir / REPORT_DIR
    out: list[Path] = []
    history, landscape, curves, importances = REPORT_FIGURES
    figures = {history: history_figure(trials),
               landscape: landscape_figure(trials),
               curves: curves_figure(trials, config.get("warmup_step")),
               importances: importance_figure(imp)}
    for stem, built in figures.items():
        out += save_figure(built.fig, out_dir / stem)
    page = study_page(trials, imp, config, {stem: built.notes for stem, built in figures.items()})
    md, html = REPORT_PAGES
    out.append(write_text(out_dir / md, page.markdown()))
    out.append(write_text(out_dir / html, page.html()))
    return out
