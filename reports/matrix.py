"""The robustness-matrix section of the report (``bench matrix``; beyond the paper).

From ``RUN/matrix/`` (bench/execute/matrix.py): the score of every trained policy at other team
sizes N', loss rates p', loss models and message delays d'. The score is the success rate,
or for a lifelong matrix (every 'ok' row has a throughput) the throughput in goals per step
(``Score``). Statistics: a seed's value is the mean over the condition's K paired episodes;
the table and bands give the mean over seeds with a 95% interval inside the score's range by
construction (reports/stats.py: ``rate_ci``, a Student t interval on the logit scale, for
success; ``positive_ci``, Cox's lognormal interval, for throughput; one seed: no interval). Figures
use the headline mode (argmax; planner for PIBT); the table lists every mode.

Outputs: matrix_heatmaps (train condition x eval condition, Bernoulli loss, per method),
matrix_degradation (score(p') at the training N and delay, one line per trained p),
matrix_bursty (Bernoulli vs Gilbert-Elliott at the same mean p', at the training N and
delay, pooled over trained p per seed), matrix_delay when the matrix has a delay d' > 0
(score(d') at the training N and p, one line per trained delay and delay model),
matrix.md (generated summary sentences, the table and the unsupported units with their
reason) and matrix.csv. Loss figures and sentences hold the delay at the cell's own
(d' = d), delay figures and sentences the loss (p' = p, Bernoulli).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import seaborn as sns
from matplotlib.axes import Axes

from algorithms.common.execution import HEADLINE, PLANNER
from reports.figures.plotting import (
    Built,
    fitted_legend,
    label_order,
    method_label,
    new_figure,
    paper_style,
    placeholder,
    ranked_legend,
)
from reports.pages.index import Entry
from reports.stats import mean_ci, positive_ci, rate_ci
from reports.writers import save_figure, write_text

KEYS = ["method", "train_n", "train_p", "train_delay", "train_delay_model", "eval_n", "eval_p", "loss_model",
        "burst_length", "eval_delay", "delay_model", "execution"]
DELAY_DEFAULTS = {"train_delay": 0.0, "train_delay_model": "fixed", "eval_delay": 0.0, "delay_model": "fixed"}


@dataclass(frozen=True)
class Score:
    """What the matrix scores: the eval column, its name in tables and figures, its unit."""

    metric: str
    column: str  # of the table: "success" or "throughput"
    label: str  # axis label
    kept: str  # "success" / "throughput" in the summary sentences
    rate: bool  # a rate in [0, 1] (axis and colour scale fixed), else from 0 up


SUCCESS = Score("success_rate", "success", "success rate", "success", True)
THROUGHPUT = Score("throughput", "throughput", "throughput (goals/step)", "throughput", False)


def score_of(df: pd.DataFrame) -> Score:
    """Throughput for a lifelong matrix (every 'ok' row has a finite throughput), else success."""
    ok = df[df["status"] == "ok"]
    lifelong = len(ok) and "throughput" in ok and bool(np.isfinite(ok["throughput"].to_numpy(dtype=float)).all())
    return THROUGHPUT if lifelong else SUCCESS


def _with_delays(df: pd.DataFrame) -> pd.DataFrame:
    """Rows with the delay columns (a frame without them is a delay-0 matrix)."""
    return df.assign(**{c: v for c, v in DELAY_DEFAULTS.items() if c not in df})


def seed_values(df: pd.DataFrame, score: Score | None = None) -> pd.DataFrame:
    """One row per (KEYS, seed): the mean of the score's metric over the condition's
    episodes ('ok' units only; burst_length 0 stands for Bernoulli, which has none)."""
    metric = (score or score_of(df)).metric
    ok = _with_delays(df[df["status"] == "ok"]).copy()
    ok["burst_length"] = ok["burst_length"].fillna(0.0)
    return ok.groupby(KEYS + ["seed"], as_index=False)[metric].mean()


def matrix_table(df: pd.DataFrame, score: Score | None = None) -> pd.DataFrame:
    """Mean score over seeds with its t interval, per KEYS (every mode); the score's column
    is named ``score.column`` ("success" or "throughput")."""
    score = score or score_of(df)
    rows = []
    for key, g in seed_values(df, score).groupby(KEYS):
        # inside the range by construction: logit t for a rate, Cox's lognormal for a count per step
        m, lo, hi = (rate_ci if score.rate else positive_ci)(g[score.metric].to_numpy())
        rows.append({**dict(zip(KEYS, key, strict=True)), score.column: m, "lo": lo, "hi": hi, "seeds": len(g)})
    return pd.DataFrame(rows, columns=KEYS + [score.column, "lo", "hi", "seeds"])


def own_delay(t: pd.DataFrame) -> pd.DataFrame:
    """Rows evaluated at the delay their cell trained at (the loss figures' slice)."""
    return t[(t["eval_delay"] == t["train_delay"]) & (t["delay_model"] == t["train_delay_model"])]


def has_delays(t: pd.DataFrame) -> bool:
    """Whether a delay other than 0 was trained or evaluated (the delay axis is in use)."""
    return bool(len(t)) and bool(((t["eval_delay"] > 0) | (t["train_delay"] > 0)).any())


def delay_label(d: float, model: str) -> str:
    """'0', '2' (fixed) or '2 geom.'."""
    return f"{d:g}" if d == 0 or model == "fixed" else f"{d:g} geom."


def _order(method: str) -> tuple[int, str]:
    """The paper's method first, then the baselines (as in every report figure)."""
    return label_order(method_label(method)), method


def headline(df: pd.DataFrame) -> pd.DataFrame:
    return df[df["execution"].isin([HEADLINE, PLANNER])]


def _loss_label(model: str, burst: float) -> str:
    return "Bernoulli" if model == "bernoulli" else f"Gilbert-Elliott b={burst:g}"


def _condition_label(key: tuple[Any, ...], delays: bool) -> str:
    """'40,0.2' or with delays '40,0.2,d2' for a heatmap key (N, p) or (N, p, d, model)."""
    n, p, d, model = tuple(key) + (0.0, "fixed")[len(key) - 2:]
    return f"{n},{p:g}" + (f",d{delay_label(d, model)}" if delays else "")


def heatmaps(table: pd.DataFrame, score: Score = SUCCESS) -> Built:
    """The score (headline mode, Bernoulli) per method: rows (N, p[, d]) trained, columns
    (N', p'[, d']) evaluated; the delays appear when the matrix has any."""
    t = headline(table)
    t = t[t["loss_model"] == "bernoulli"]
    delays = has_delays(t)
    rows_by = ["train_n", "train_p"] + (["train_delay", "train_delay_model"] if delays else [])
    cols_by = ["eval_n", "eval_p"] + (["eval_delay", "delay_model"] if delays else [])
    methods = sorted(t["method"].unique(), key=_order)
    top = 1.0 if score.rate else max(float(t[score.column].max()) if len(t) else 1.0, 1e-9)
    with paper_style():
        ncols = max(len(t.drop_duplicates(cols_by)), 1)
        fig = new_figure(1.0 + 1.1 * max(len(methods), 1), max(3.5, 0.45 * ncols + 1.2))
        axes = fig.subplots(max(len(methods), 1), 1, squeeze=False)[:, 0]
        if not methods:
            placeholder(axes[0], "no 'ok' matrix units with Bernoulli loss")
            return Built(fig, ["no data"])
        for ax, method in zip(axes, methods, strict=True):
            g = t[t["method"] == method]
            wide = g.pivot_table(index=rows_by, columns=cols_by, values=score.column)
            ax.imshow(wide.to_numpy(dtype=float), vmin=0, vmax=top, cmap="viridis", aspect="auto")
            for (i, j), v in np.ndenumerate(wide.to_numpy(dtype=float)):
                if not math.isnan(v):
                    ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=5,
                            color="white" if v < 0.5 * top else "black")
            ax.set_xticks(range(wide.shape[1]), [_condition_label(k, delays) for k in wide.columns],
                          rotation=90)
            ax.set_yticks(range(wide.shape[0]), [_condition_label(k, delays) for k in wide.index])
            what = "N,p,d x evaluated N',p',d'" if delays else "N,p x evaluated N',p'"
            ax.set_title(f"{method_label(method)}: {score.kept} (trained {what})")
            ax.grid(False)
    return Built(fig, ["mean over seeds; headline mode (argmax, planner for PIBT); Bernoulli loss"])


def _band(ax: Axes, g: pd.DataFrame, label: str, color: Any, style: str = "-", x: str = "eval_p",
          column: str = "success") -> None:
    """score(x) with its interval band (when there are >= 2 seeds)."""
    g = g.sort_values(x)
    ax.plot(g[x], g[column], style, marker="o", color=color, label=label)
    if g["lo"].notna().any():
        ax.fill_between(g[x], g["lo"], g["hi"], color=color, alpha=0.2, linewidth=0)


def _score_axis(ax: Axes, score: Score) -> None:
    ax.set_ylabel(score.label)
    if score.rate:
        ax.set_ylim(-0.02, 1.02)
    else:
        ax.set_ylim(bottom=0.0)


def degradation(table: pd.DataFrame, score: Score = SUCCESS) -> Built:
    """score(p') at the training team size and delay, one line per trained p (Bernoulli, headline)."""
    t = own_delay(headline(table))
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
        delays = has_delays(t)
        for ax, method in zip(axes, methods, strict=True):
            for (n, p, d, dm), g in t[t["method"] == method].groupby(
                    ["train_n", "train_p", "train_delay", "train_delay_model"]):
                label = f"N={n}, trained p={p:g}" + (f", d={delay_label(d, dm)}" if delays else "")
                _band(ax, g, label, colors[p], "-" if n == t["train_n"].min() else "--", column=score.column)
            ax.set_title(method_label(method))
            ax.set_xlabel("evaluation loss p'")
            _score_axis(ax, score)
            ax.legend(loc="best", frameon=True, framealpha=0.8)
    return Built(fig, ["N' = training N, d' = training delay; Bernoulli loss; band: t 95% interval over seeds"])


def delay_degradation(table: pd.DataFrame, score: Score = SUCCESS) -> Built:
    """score(d') at the training team size and loss (p' = p, Bernoulli, headline), one line
    per trained delay and delay model (fixed d': solid; geometric d': dashed)."""
    t = headline(table)
    t = t[(t["loss_model"] == "bernoulli") & (t["eval_n"] == t["train_n"]) & (t["eval_p"] == t["train_p"])]
    methods = sorted(t["method"].unique(), key=_order)
    with paper_style():
        fig = new_figure(1.6 * max(len(methods), 1))
        axes = fig.subplots(max(len(methods), 1), 1, squeeze=False)[:, 0]
        if not methods:
            placeholder(axes[0], "no unit at the training team size and loss")
            return Built(fig, ["no data"])
        trained = sorted(set(map(tuple, t[["train_delay", "train_delay_model"]].to_numpy().tolist())))
        colors = dict(zip(trained, sns.color_palette("mako", len(trained)), strict=True))
        several = len(t.drop_duplicates(["train_n", "train_p"])) > 1
        for ax, method in zip(axes, methods, strict=True):
            mine = t[t["method"] == method]
            for (n, p, d, dm, model), g in mine.groupby(
                    ["train_n", "train_p", "train_delay", "train_delay_model", "delay_model"]):
                if model == "geometric":  # d' = 0 has no model: it starts the geometric line too
                    zero = mine[(mine["train_n"] == n) & (mine["train_p"] == p) & (mine["train_delay"] == d)
                                & (mine["train_delay_model"] == dm) & (mine["eval_delay"] == 0)]
                    g = pd.concat([zero, g])
                label = (f"trained d={delay_label(d, dm)}" + (f" (N={n}, p={p:g})" if several else "")
                         + (", geometric d'" if model == "geometric" else ""))
                _band(ax, g, label, colors[(d, dm)], "--" if model == "geometric" else "-", x="eval_delay",
                      column=score.column)
            ax.set_title(method_label(method))
            ax.set_xlabel("evaluation mean message delay d' (steps)")
            _score_axis(ax, score)
        handles, labels = ranked_legend(axes)  # one legend below the panels: bands fill the axes
        fitted_legend(fig, handles, labels, "outside lower center", max_cols=2)
    return Built(fig, ["N' = training N, p' = training p, Bernoulli loss; band: t 95% interval over seeds"])


def bursty(df: pd.DataFrame, score: Score = SUCCESS) -> tuple[Built, pd.DataFrame]:
    """Bernoulli vs Gilbert-Elliott at the same mean p' (training N and delay; per seed pooled over trained p)."""
    sv = own_delay(headline(seed_values(df, score)))
    sv = sv[sv["eval_n"] == sv["train_n"]]
    metric = score.metric
    pooled = sv.groupby(["method", "eval_p", "loss_model", "burst_length", "seed"], as_index=False)[metric].mean()
    rows = []
    for key, g in pooled.groupby(["method", "eval_p", "loss_model", "burst_length"]):
        m, lo, hi = mean_ci(g[metric].to_numpy())
        rows.append({"method": key[0], "eval_p": key[1], "loss_model": key[2], "burst_length": key[3],
                     score.column: m, "lo": lo, "hi": hi, "seeds": len(g)})
    t = pd.DataFrame(rows, columns=["method", "eval_p", "loss_model", "burst_length", score.column, "lo", "hi",
                                    "seeds"])
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
                    _band(ax, g, _loss_label(mrow["loss_model"], mrow["burst_length"]), color, column=score.column)
            ax.set_title(method_label(method))
            ax.set_xlabel("mean evaluation loss p'")
            _score_axis(ax, score)
            ax.legend(loc="best", frameon=True, framealpha=0.8)
    return Built(fig, ["N' = training N, d' = training delay, per seed the mean over trained p; "
                       "band: t 95% interval over seeds"]), t


def _kept(wide: pd.DataFrame, own: Any, target: Any, method: str, score: Score) -> str:
    """'X keeps 50% (95% CI ..) of its success (0.80 -> 0.40, 3 seeds)': the per-seed ratio
    score(target) / score(own), mean over seeds with its t interval."""
    own_v, far = wide[own], wide[target]
    ratio = (far / own_v).where(own_v > 0)
    m, lo, hi = mean_ci(ratio.to_numpy())
    if math.isnan(m):
        return f"{method_label(method)} has no {score.kept} at its training condition"
    ci = f" (95% CI {100 * lo:.0f}-{100 * hi:.0f}%)" if not math.isnan(lo) else ""
    return (f"{method_label(method)} keeps {100 * m:.0f}%{ci} of its {score.kept} "
            f"({own_v.mean():.2f} -> {far.mean():.2f}, {len(wide)} seed{'s' * (len(wide) != 1)})")


def summary_sentences(df: pd.DataFrame, score: Score | None = None) -> list[str]:
    """Per trained (N, p[, d]): the share of its score each method keeps at the largest p'
    (Bernoulli, N' = N, d' = d, headline mode) and, with a delay axis, at the largest fixed
    d' (p' = p, Bernoulli, N' = N); mean over seeds of the per-seed ratio with its t interval."""
    score = score or score_of(df)
    sv = headline(seed_values(df, score))
    sv = sv[(sv["loss_model"] == "bernoulli") & (sv["eval_n"] == sv["train_n"])]
    delays = has_delays(sv)
    out = []
    for (n, p, d, dm), g in own_delay(sv).groupby(["train_n", "train_p", "train_delay", "train_delay_model"]):
        target = g["eval_p"].max()
        if target == p or not (g["eval_p"] == p).any():
            continue
        parts = []
        for method, gm in sorted(g.groupby("method"), key=lambda kv: _order(kv[0])):
            wide = gm.pivot_table(index="seed", columns="eval_p", values=score.metric)
            if p in wide and target in wide:
                parts.append(_kept(wide, p, target, method, score))
        at = f", d={delay_label(d, dm)}" if delays else ""
        if parts:
            out.append(f"Trained at N={n}, p={p:g}{at} and evaluated at p'={target:g} (Bernoulli, N'={n}"
                       f"{', same delay' if delays else ''}): " + "; ".join(parts) + ".")
    fixed = sv[(sv["eval_p"] == sv["train_p"]) & (sv["delay_model"] == "fixed")]
    for (n, p, d, dm), g in fixed.groupby(["train_n", "train_p", "train_delay", "train_delay_model"]) if delays else []:
        own = d if dm == "fixed" else None
        target = g["eval_delay"].max()
        if own is None or target == own or not (g["eval_delay"] == own).any():
            continue
        parts = []
        for method, gm in sorted(g.groupby("method"), key=lambda kv: _order(kv[0])):
            wide = gm.pivot_table(index="seed", columns="eval_delay", values=score.metric)
            if own in wide and target in wide:
                parts.append(_kept(wide, own, target, method, score))
        if parts:
            out.append(f"Trained at N={n}, p={p:g}, d={d:g} and evaluated at a fixed delay d'={target:g} "
                       f"(p'={p:g}, Bernoulli, N'={n}): " + "; ".join(parts) + ".")
    return out


def matrix_markdown(table: pd.DataFrame, sentences: list[str], unsupported: pd.DataFrame,
                    score: Score = SUCCESS) -> str:
    delays = has_delays(table) or (len(unsupported) > 0 and has_delays(_with_delays(unsupported)))
    lines = ["# Robustness matrix (bench matrix)", "",
             f"{score.label.capitalize()} of every trained policy at other team sizes N', loss rates p'"
             f"{', loss models and message delays' if delays else ' and loss models'}, on scenarios shared by "
             "every method and training condition. Mean over seeds (a seed: the mean over the condition's "
             "episodes), t 95% interval.", "", "## Summary", ""]
    lines += [f"- {s}" for s in sentences] or ["- (no training condition evaluated at a larger p')"]
    d_head, d_rule = (" d |", "---|") if delays else ("", "")
    e_head = " d' |" if delays else ""
    lines += ["", "## Every condition and execution mode", "",
              f"| method | N | p |{d_head} N' | p' | loss |{e_head} mode | {score.column} | 95% CI | seeds |",
              f"|---|---|---|{d_rule}---|---|---|{d_rule}---|---|---|---|"]
    for r in table.itertuples():
        ci = "" if math.isnan(r.lo) else f"{r.lo:.3f}-{r.hi:.3f}"
        trained = f" {delay_label(r.train_delay, r.train_delay_model)} |" if delays else ""
        evaluated = f" {delay_label(r.eval_delay, r.delay_model)} |" if delays else ""
        lines.append(f"| {r.method} | {r.train_n} | {r.train_p:g} |{trained} {r.eval_n} | {r.eval_p:g} | "
                     f"{_loss_label(r.loss_model, r.burst_length)} |{evaluated} {r.execution} | "
                     f"{getattr(r, score.column):.3f} | {ci} | {r.seeds} |")
    if len(unsupported):
        lines += ["", "## Units that cannot run", "",
            f"| method | cell | N' | p' | loss |{e_head} reason |", f"|---|---|---|---|---|{d_rule}---|"]
        for r in _with_delays(unsupported).itertuples():
            evaluated = f" {delay_label(r.eval_delay, r.delay_model)} |" if delays else ""
            lines.append(f"| {r.method} | {r.cell_id} | {r.eval_n} | {r.eval_p:g} | "
                         f"{_loss_label(r.loss_model, r.burst_length)} |{evaluated} {r.reason} |")
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
    score = score_of(df)
    table = matrix_table(df, score)
    sentences = summary_sentences(df, score)
    unsupported = df[df["status"] != "ok"].drop_duplicates(["cell_id", "condition"])
    entries = []
    seeds = int(df["seed"].nunique()) if "seed" in df else 0
    common = (f" {score.label.capitalize()} in argmax execution (planner for PIBT), mean over {seeds} seed(s) of "
              "the per-seed evaluation means; every method evaluated on the same scenarios per condition.")
    delays = has_delays(table)
    figures = [
        ("matrix_heatmaps", f"Robustness matrix: {score.kept}, trained x evaluated condition", heatmaps(table, score),
         "Rows: the condition a policy was trained at (N, p" + (", d" if delays else "") + "); columns: the "
         "evaluation condition (N', p'" + (", d'" if delays else "") + "; Bernoulli loss)."),
        ("matrix_degradation", f"Robustness matrix: {score.kept}(p') per trained p", degradation(table, score),
         f"{score.label.capitalize()} against the evaluation loss probability p' (Bernoulli"
         + (", at the training delay" if delays else "") + "), one line per trained p; band: "
         "95% Student t interval over seeds."),
        ("matrix_bursty", "Robustness matrix: Bernoulli vs bursty loss at the same mean", bursty(df, score)[0],
         "Bernoulli loss against Gilbert-Elliott loss with the same mean p' (burst lengths as labelled)."),
    ]
    if delays:
        figures.append(("matrix_delay", f"Robustness matrix: {score.kept}(d') per trained delay",
                        delay_degradation(table, score),
                        f"{score.label.capitalize()} against the evaluation mean message delay d' (at the training "
                        "N and p, Bernoulli loss), one line per trained delay (dashed: geometric d'); band: 95% "
                        "Student t interval over seeds."))
    for stem, title, built, what in figures:
        caption = what + common
        save_figure(built.fig, out / stem, caption)
        entries.append(Entry(title, (f"{stem}.png", f"{stem}.pdf"), tuple(built.notes), image=f"{stem}.png",
                             caption=caption))
    write_text(out / "matrix.md", matrix_markdown(table, sentences, unsupported, score))
    write_text(out / "matrix.csv", table.to_csv(index=False))
    notes = tuple(sentences) + tuple(problems)
    if len(unsupported):
        notes += (f"{len(unsupported)} unit(s) cannot run; see matrix.md",)
    entries.append(Entry("Robustness matrix: summary and table", ("matrix.md", "matrix.csv"), notes,
                         tables=(("Robustness matrix: one row per trained cell condition, evaluation "
                                  "condition and execution mode (matrix.csv has every column).", table),)))
    return entries
