"""The robustness-matrix section of the report (``bench matrix``; beyond the paper).

From ``RUN/matrix/`` (bench/execute/matrix.py): success rate of every trained policy at other team
sizes N', loss rates p' and loss models. Statistics: a seed's value is the mean over the
condition's K paired episodes; the table and bands give the mean over seeds with a
Student t 95% interval (reports/stats.py ``mean_ci``; one seed: no interval). Figures use
the headline mode (argmax; planner for PIBT); the table lists every mode.

Outputs: matrix_heatmaps (train condition x eval condition, Bernoulli loss, per method),
matrix_degradation (success(p') at the training N, one line per trained p),
matrix_bursty (Bernoulli vs Gilbert-Elliott at the same mean p', at the training N, pooled
over trained p per seed), matrix.md (generated summary sentences, the table and the
unsupported units with their reason) and matrix.csv.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import seaborn as sns
from matplotlib.axes import Axes

from algorithms.common.execution import HEADLINE, PLANNER
from reports.figures.plotting import (
    Built,
    label_order,
    method_label,
    new_figure,
    paper_style,
    placeholder,
)
from reports.pages.index import Entry
from reports.stats import mean_ci
from reports.writers import save_figure, write_text

KEYS = ["method", "train_n", "train_p", "eval_n", "eval_p", "loss_model", "burst_length", "execution"]
METRIC = "success_rate"


def seed_values(df: pd.DataFrame, metric: str = METRIC) -> pd.DataFrame:
    """One row per (KEYS, seed): the mean of ``metric`` over the condition's episodes
    ('ok' units only; burst_length 0 stands for Bernoulli, which has none)."""
    ok = df[df["status"] == "ok"].copy()
    ok["burst_length"] = ok["burst_length"].fillna(0.0)
    return ok.groupby(KEYS + ["seed"], as_index=False)[metric].mean()


def matrix_table(df: pd.DataFrame) -> pd.DataFrame:
    """Mean success over seeds with its t interval, per KEYS (every mode)."""
    rows = []
    for key, g in seed_values(df).groupby(KEYS):
        m, lo, hi = mean_ci(g[METRIC].to_numpy())
        rows.append({**dict(zip(KEYS, key, strict=True)), "success": m, "lo": lo, "hi": hi, "seeds": len(g)})
    return pd.DataFrame(rows, columns=KEYS + ["success", "lo", "hi", "seeds"])


def _order(method: str) -> tuple[int, str]:
    """The paper's method first, then the baselines (as in every report figure)."""
    return label_order(method_label(method)), method


def headline(df: pd.DataFrame) -> pd.DataFrame:
    return df[df["execution"].isin([HEADLINE, PLANNER])]


def _loss_label(model: str, burst: float) -> str:
    return "Bernoulli" if model == "bernoulli" else f"Gilbert-Elliott b={burst:g}"


def heatmaps(table: pd.DataFrame) -> Built:
    """Success (headline mode, Bernoulli) per method: rows (N, p) trained, columns (N', p')."""
    t = headline(table)
    t = t[t["loss_model"] == "bernoulli"]
    methods = sorted(t["method"].unique(), key=_order)
    with paper_style():
        ncols = max(len(t.drop_duplicates(["eval_n", "eval_p"])), 1)
        fig = new_figure(1.0 + 1.1 * max(len(methods), 1), max(3.5, 0.45 * ncols + 1.2))
        axes = fig.subplots(max(len(methods), 1), 1, squeeze=False)[:, 0]
        if not methods:
            placeholder(axes[0], "no 'ok' matrix units with Bernoulli loss")
            return Built(fig, ["no data"])
        for ax, method in zip(axes, methods, strict=True):
            g = t[t["method"] == method]
            wide = g.pivot_table(index=["train_n", "train_p"], columns=["eval_n", "eval_p"], values="success")
            ax.imshow(wide.to_numpy(dtype=float), vmin=0, vmax=1, cmap="viridis", aspect="auto")
            for (i, j), v in np.ndenumerate(wide.to_numpy(dtype=float)):
                if not math.isnan(v):
                    ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=5,
                            color="white" if v < 0.5 else "black")
            ax.set_xticks(range(wide.shape[1]), [f"{n},{p:g}" for n, p in wide.columns], rotation=90)
            ax.set_yticks(range(wide.shape[0]), [f"{n},{p:g}" for n, p in wide.index])
            ax.set_title(f"{method_label(method)}: success (trained N,p x evaluated N',p')")
            ax.grid(False)
    return Built(fig, ["mean over seeds; headline mode (argmax, planner for PIBT); Bernoulli loss"])


def _band(ax: Axes, g: pd.DataFrame, label: str, color: Any, style: str = "-") -> None:
    """success(p') with its interval band (when there are >= 2 seeds)."""
    g = g.sort_values("eval_p")
    ax.plot(g["eval_p"], g["success"], style, marker="o", color=color, label=label)
    if g["lo"].notna().any():
        ax.fill_between(g["eval_p"], g["lo"], g["hi"], color=color, alpha=0.2, linewidth=0)


def degradation(table: pd.DataFrame) -> Built:
    """success(p') at the training team size, one line per trained p (Bernoulli, headline)."""
    t = headline(table)
    t = t[(t["loss_model"] == "bernoulli") & (t["eval_n"] == t["train_n"])]
    methods = sorted(t["method"].unique(), key=_order)
    with paper_style():
        fig = new_figure(1.6 * max(len(methods), 1))
        axes = fig.subplots(max(len(methods), 1), 1, squeeze=False)[:, 0]
        if not methods:
            placeholder(axes[0], "no unit at the training team size")
            return Built(fig, ["no data"])
        ps = sorted(t["train_p"].unique())
        colors = dict(zip(ps, sns.color_palette("rocket", len(ps)), strict=True))
        for ax, method in zip(axes, methods, strict=True):
            for (n, p), g in t[t["method"] == method].groupby(["train_n", "train_p"]):
                _band(ax, g, f"N={n}, trained p={p:g}", colors[p], "-" if n == t["train_n"].min() else "--")
            ax.set_title(method_label(method))
            ax.set_xlabel("evaluation loss p'")
            ax.set_ylabel("success rate")
            ax.set_ylim(-0.02, 1.02)
            ax.legend(loc="best", frameon=True, framealpha=0.8)
    return Built(fig, ["N' = training N; Bernoulli loss; band: t 95% interval over seeds"])


def bursty(df: pd.DataFrame) -> tuple[Built, pd.DataFrame]:
    """Bernoulli vs Gilbert-Elliott at the same mean p' (training N; per seed pooled over trained p)."""
    sv = headline(seed_values(df))
    sv = sv[sv["eval_n"] == sv["train_n"]]
    pooled = sv.groupby(["method", "eval_p", "loss_model", "burst_length", "seed"], as_index=False)[METRIC].mean()
    rows = []
    for key, g in pooled.groupby(["method", "eval_p", "loss_model", "burst_length"]):
        m, lo, hi = mean_ci(g[METRIC].to_numpy())
        rows.append({"method": key[0], "eval_p": key[1], "loss_model": key[2], "burst_length": key[3],
                     "success": m, "lo": lo, "hi": hi, "seeds": len(g)})
    t = pd.DataFrame(rows, columns=["method", "eval_p", "loss_model", "burst_length", "success", "lo", "hi", "seeds"])
    methods = sorted(t["method"].unique(), key=_order)
    with paper_style():
        fig = new_figure(1.6 * max(len(methods), 1))
        axes = fig.subplots(max(len(methods), 1), 1, squeeze=False)[:, 0]
        if not methods:
            placeholder(axes[0], "no unit at the training team size")
            return Built(fig, ["no data"]), t
        models = t.drop_duplicates(["loss_model", "burst_length"]).sort_values(["loss_model", "burst_length"])
        palette = sns.color_palette("colorblind", len(models))
        for ax, method in zip(axes, methods, strict=True):
            for color, (_, mrow) in zip(palette, models.iterrows(), strict=True):
                g = t[(t["method"] == method) & (t["loss_model"] == mrow["loss_model"])
                      & (t["burst_length"] == mrow["burst_length"])]
                if len(g):
                    _band(ax, g, _loss_label(mrow["loss_model"], mrow["burst_length"]), color)
            ax.set_title(method_label(method))
            ax.set_xlabel("mean evaluation loss p'")
            ax.set_ylabel("success rate")
            ax.set_ylim(-0.02, 1.02)
            ax.legend(loc="best", frameon=True, framealpha=0.8)
    return Built(fig, ["N' = training N, per seed the mean over trained p; band: t 95% interval over seeds"]), t


def summary_sentences(df: pd.DataFrame) -> list[str]:
    """Per trained (N, p): the share of its success each method keeps at the largest p'
    (Bernoulli, N' = N, headline mode), mean over seeds of the per-seed ratio with its t interval."""
    sv = headline(seed_values(df))
    sv = sv[(sv["loss_model"] == "bernoulli") & (sv["eval_n"] == sv["train_n"])]
    out = []
    for (n, p), g in sv.groupby(["train_n", "train_p"]):
        target = g["eval_p"].max()
        if target == p or not (g["eval_p"] == p).any():
            continue
        parts = []
        for method, gm in sorted(g.groupby("method"), key=lambda kv: _order(kv[0])):
            wide = gm.pivot_table(index="seed", columns="eval_p", values=METRIC)
            if p not in wide or target not in wide:
                continue
            own, far = wide[p], wide[target]
            ratio = (far / own).where(own > 0)
            m, lo, hi = mean_ci(ratio.to_numpy())
            if math.isnan(m):
                parts.append(f"{method_label(method)} has no success at its training condition")
                continue
            ci = f" (95% CI {100 * lo:.0f}-{100 * hi:.0f}%)" if not math.isnan(lo) else ""
            parts.append(f"{method_label(method)} keeps {100 * m:.0f}%{ci} of its success "
                         f"({own.mean():.2f} -> {far.mean():.2f}, {len(wide)} seed{'s' * (len(wide) != 1)})")
        if parts:
            out.append(f"Trained at N={n}, p={p:g} and evaluated at p'={target:g} (Bernoulli, N'={n}): "
                       + "; ".join(parts) + ".")
    return out


def matrix_markdown(table: pd.DataFrame, sentences: list[str], unsupported: pd.DataFrame) -> str:
    lines = ["# Robustness matrix (bench matrix)", "",
             "Success rate of every trained policy at other team sizes N', loss rates p' and loss "
             "models, on scenarios shared by every method and training condition. Mean over seeds "
             "(a seed: the mean over the condition's episodes), t 95% interval.", "", "## Summary", ""]
    lines += [f"- {s}" for s in sentences] or ["- (no training condition evaluated at a larger p')"]
    lines += ["", "## Every condition and execution mode", "",
              "| method | N | p | N' | p' | loss | mode | success | 95% CI | seeds |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for r in table.itertuples():
        ci = "" if math.isnan(r.lo) else f"{r.lo:.3f}-{r.hi:.3f}"
        lines.append(f"| {r.method} | {r.train_n} | {r.train_p:g} | {r.eval_n} | {r.eval_p:g} | "
                     f"{_loss_label(r.loss_model, r.burst_length)} | {r.execution} | {r.success:.3f} | {ci} | "
                     f"{r.seeds} |")
    if len(unsupported):
        lines += ["", "## Units that cannot run", "",
            "| method | cell | N' | p' | loss | reason |", "|---|---|---|---|---|---|"]
        for r in unsupported.itertuples():
            lines.append(f"| {r.method} | {r.cell_id} | {r.eval_n} | {r.eval_p:g} | "
                         f"{_loss_label(r.loss_model, r.burst_length)} | {r.reason} |")
    return "\n".join(lines) + "\n"


def matrix_entries(run_dir: Path | str, out: Path) -> list[Entry]:
    """Build the section when ``RUN/matrix/`` holds units; [] otherwise (files written by
    reports/writers.py, atomically)."""
    from bench.execute.matrix import read_matrix

    problems: list[str] = []
    table_pa = read_matrix(run_dir, problems)
    if table_pa is None:
        return [Entry("Robustness matrix: no readable unit", (), tuple(problems))] if problems else []
    df = table_pa.to_pandas()
    table = matrix_table(df)
    sentences = summary_sentences(df)
    unsupported = df[df["status"] != "ok"].drop_duplicates(["cell_id", "condition"])
    entries = []
    seeds = int(df["seed"].nunique()) if "seed" in df else 0
    common = (f" Success rate in argmax execution (planner for PIBT), mean over {seeds} seed(s) of the "
              "per-seed evaluation means; every method evaluated on the same scenarios per condition.")
    for stem, title, built, what in (
        ("matrix_heatmaps", "Robustness matrix: success, trained x evaluated condition", heatmaps(table),
         "Rows: the condition a policy was trained at (N, p); columns: the evaluation condition (N', p', loss model)."),
        ("matrix_degradation", "Robustness matrix: success(p') per trained p", degradation(table),
         "Success against the evaluation loss probability p' (Bernoulli), one line per trained p; band: "
         "95% Student t interval over seeds."),
        ("matrix_bursty", "Robustness matrix: Bernoulli vs bursty loss at the same mean", bursty(df)[0],
         "Bernoulli loss against Gilbert-Elliott loss with the same mean p' (burst lengths as labelled)."),
    ):
        caption = what + common
        save_figure(built.fig, out / stem, caption)
        entries.append(Entry(title, (f"{stem}.png", f"{stem}.pdf"), tuple(built.notes), image=f"{stem}.png",
                             caption=caption))
    write_text(out / "matrix.md", matrix_markdown(table, sentences, unsupported))
    write_text(out / "matrix.csv", table.to_csv(index=False))
    notes = tuple(sentences) + tuple(problems)
    if len(unsupported):
        notes += (f"{len(unsupported)} unit(s) cannot run; see matrix.md",)
    entries.append(Entry("Robustness matrix: summary and table", ("matrix.md", "matrix.csv"), notes,
                         tables=(("Robustness matrix: one row per trained cell condition, evaluation "
                                  "condition and execution mode (matrix.csv has every column).", table),)))
    return entries
