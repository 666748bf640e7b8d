"""The study report page (``study.md`` and ``study.html``): what was run, the best
configuration with its CI, whether pruning was justified, every configuration and trial.

``study_page`` is a pure function of the trials frame, the importances and the study
config (``study.json``); it returns a ``Page`` of sections that renders to Markdown and to
a self-contained HTML page (tables via ``DataFrame.to_html``, figures by relative path, so
the report folder can be copied).
"""
from __future__ import annotations

import html
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from studies.points import coverage, point_table
from studies.pruning import step_correlations
from studies.space import plain
from studies.trial_columns import FILTER_RATES, TRIAL_COLUMNS, param_columns

# the safety filter's rates, shown beside the success rate wherever a trial recorded them
RATE_LABELS = dict(zip(FILTER_RATES, ("fallback", "corrections"), strict=True))
FIGURES = (("study_history", "Optimization history"),
           ("study_landscape", "Landscape: L x |R_z|, or the objective per parameter value (all finished trials)"),
           ("study_curves", "Intermediate values per trial"),
           ("study_importances", "Parameter importances"))


@dataclass
class Section:
    title: str
    paragraphs: list[str] = field(default_factory=list)
    table: pd.DataFrame | None = None
    figures: list[tuple[str, str, list[str]]] = field(default_factory=list)  # (stem, caption, notes)


@dataclass
class Page:
    title: str
    sections: list[Section]

    def markdown(self) -> str:
        out = [f"# {self.title}", ""]
        for s in self.sections:
            out += [f"## {s.title}", ""]
            for p in s.paragraphs:
                out += [p, ""]
            if s.table is not None:
                out += [_md_table(s.table), ""]
            for stem, caption, notes in s.figures:
                out += [f"![{caption}]({stem}.png)", "", f"*{caption}.*" + "".join(f" {n}." for n in notes), ""]
        return "\n".join(out).rstrip() + "\n"

    def html(self) -> str:
        body = [f"<h1>{html.escape(self.title)}</h1>"]
        for s in self.sections:
            body.append(f"<h2>{html.escape(s.title)}</h2>")
            body += [f"<p>{html.escape(p)}</p>" for p in s.paragraphs]
            if s.table is not None:
                body.append('<div class="wide">'  # a wide table scrolls inside the page, not the page
                            + s.table.to_html(index=False, na_rep="", border=0, classes="tbl", escape=True) + "</div>")
            for stem, caption, notes in s.figures:
                text = html.escape(caption + "." + "".join(f" {n}." for n in notes))
                body.append(f'<figure><img src="{stem}.png" alt="{html.escape(caption)}">'
                            f"<figcaption>{text}</figcaption></figure>")
        style = ("body{font-family:DejaVu Sans,Helvetica,Arial,sans-serif;max-width:1100px;margin:2em auto;"
                 "padding:0 1em;color:#222}table.tbl{border-collapse:collapse;font-size:13px;margin:.5em 0}"
                 ".tbl th,.tbl td{border-bottom:1px solid #ddd;padding:2px 8px;text-align:right}"
                 "figure{margin:1em 0}img{max-width:100%}figcaption{font-size:13px;color:#444}.wide{overflow-x:auto}")
        return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
                f"<title>{html.escape(self.title)}</title><style>{style}</style></head><body>\n"
                + "\n".join(body) + "\n</body></html>\n")


def _md_table(df: pd.DataFrame) -> str:
    def cell(v: Any) -> str:
        return "" if v is None or (isinstance(v, float) and math.isnan(v)) or v is pd.NA else str(v).replace("|", "/")

    head = "| " + " | ".join(map(str, df.columns)) + " |"
    rule = "|" + "|".join("---" for _ in df.columns) + "|"
    rows = ["| " + " | ".join(cell(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join([head, rule, *rows])


def _f(x: Any, digits: int = 3) -> str:
    return "" if x is None or pd.isna(x) else f"{float(x):.{digits}f}"


def _pct(x: Any) -> str:
    return "" if x is None or pd.isna(x) else f"{float(x):.1%}"


def correlation_table(trials: pd.DataFrame, warmup: int | None, min_rho: float | None,
                      batch_episodes: int | None = None) -> pd.DataFrame:
    """step, training episodes, complete trials, Spearman rho (value at step vs final), and
    whether pruning may act at that step (after the warm-up and rho >= ``min_rho``)."""
    comp = trials[(trials["state"] == "COMPLETE") & trials["value"].notna()]
    texts = comp["intermediate_json"].fillna("{}") if "intermediate_json" in comp else ["{}"] * len(comp)
    inter = [{int(k): v for k, v in json.loads(s).items()} for s in texts]
    rows = step_correlations(inter, comp["value"].tolist())
    out = []
    for r in rows:
        may = warmup is not None and r["step"] >= warmup
        gate = "" if warmup is None else (
            "no (warm-up)" if not may
            else ("yes" if min_rho is not None and r["rho"] >= min_rho else "no (rho too low)"))
        out.append({"update": r["step"],
                    "training episodes": r["step"] * batch_episodes if batch_episodes else "",
                    "complete trials": r["n"], "Spearman rho": _f(r["rho"], 2), "pruning may act": gate})
    return pd.DataFrame(out, columns=["update", "training episodes", "complete trials", "Spearman rho",
                                      "pruning may act"])


def study_page(trials: pd.DataFrame, imp: Mapping[str, Any], config: Mapping[str, Any],
               notes: Mapping[str, list[str]] | None = None) -> Page:
    """The report of one study (see the module docstring)."""
    notes = notes or {}
    trials = trials.assign(**{c: pd.NA for c in TRIAL_COLUMNS if c not in trials})
    name = str(trials["study"].iloc[0]) if len(trials) else str(config.get("study", "?"))
    replicates = int(config.get("replicates", 2))
    names = param_columns(trials)
    exhaustive = config.get("search_resolved") == "grid" and config.get("space_size")
    n_points = int(config["space_size"]) if exhaustive else None
    sections = [_setup(trials, config, replicates, names), _best(trials, replicates, names, n_points),
                _pruning(trials, config), _points(trials, replicates, names), _trials(trials, names),
                _importances(imp),
                Section("Figures", figures=[(stem, cap, list(notes.get(stem, []))) for stem, cap in FIGURES])]
    return Page(f"Study {name}", sections)


def _setup(trials: pd.DataFrame, config: Mapping[str, Any], replicates: int, names: list[str]) -> Section:
    counts = trials["state"].value_counts().to_dict()
    paras = []
    if config:
        space = config.get("space") or {}
        paras.append(
            f"{config.get('method', '?')}, N={config.get('n_robots', '?')}, p={config.get('loss_p', '?')}, "
            f"layout {config.get('layout', '?')}, Z={config.get('groups', '?')}; per trial "
            f"{config.get('episodes', '?')} training episodes of horizon {config.get('horizon', '?')} "
            f"({config.get('iterations', '?')} updates of {config.get('batch_episodes', '?')} episodes), "
            f"an intermediate evaluation every {config.get('eval_every', '?')} update(s) on "
            f"{int(config.get('report_chunks', 1)) * int(config.get('eval_chunk', 10))} episodes, final "
            f"evaluation on {config.get('eval_episodes', '?')} episodes; study seed {config.get('seed', '?')}.")
        paras.append(
            "Space: " + "; ".join(f"{k} in {list(v)}" for k, v in space.items())
            + f" ({config.get('space_size', '?')} configurations). Search: "
            + (f"exhaustive grid, {replicates} seed replicate(s) per configuration (replicate r of "
               "every configuration trains with the same seed)" if config.get("search_resolved") == "grid"
               else f"TPE with {replicates} replicate(s) of every configuration it proposes")
            + ". Pruner: " + (f"median rule from update {config.get('warmup_step')} "
                              f"(warm-up {config.get('prune_warmup')}) when the rank correlation at the step "
                              f">= {config.get('prune_min_rho')}" if config.get("warmup_step") else "none") + ".")
        if config.get("space_size"):
            paras.append("Coverage: " + coverage(trials, int(config["space_size"]), replicates) + ".")
    paras.append("Trials: " + ", ".join(f"{k.lower()} {v}" for k, v in sorted(counts.items())) + ".")
    return Section("Setup", paras)


def _best(trials: pd.DataFrame, replicates: int, names: list[str], n_points: int | None) -> Section:
    from envs.errors import BenchError
    from studies.points import best_point

    try:
        b = best_point(trials, replicates, n_points)
    except BenchError as exc:
        return Section("Best configuration", [f"Withheld: {exc}."])
    label = ", ".join(f"{n}={plain(b[n])}" for n in names)
    return Section("Best configuration", [
        f"{label}: mean objective {b['value']:.4f} over {int(b['complete'])} replicates, 95% CI "
        f"[{_f(b['ci_low'], 4)}, {_f(b['ci_high'], 4)}] (Student t on the logit scale); "
        f"mean success rate {b['success_rate']:.3f}"
        + "".join(f" ({what} {_pct(b[key])})" for key, what in RATE_LABELS.items() if pd.notna(b.get(key)))
        + f", mean team return {b['team_return']:.2f}; trials {b['trials']}.",
        f"Chosen by the mean over replicates among configurations with {replicates} complete and no "
        "pruned replicate; overlapping CIs in the table below mean the ranking is not settled."])


def _pruning(trials: pd.DataFrame, config: Mapping[str, Any]) -> Section:
    warmup = config.get("warmup_step")
    min_rho = config.get("prune_min_rho")
    table = correlation_table(trials, warmup, min_rho if warmup else None, config.get("batch_episodes"))
    paras = ["Spearman rank correlation, over the complete trials, between the objective at each "
             "intermediate evaluation and the trial's final objective. Pruning is justified only where "
             "it is high. Complete trials are a survivor sample (pruned ones have no final value), "
             "which narrows their range and tends to lower the correlation."]
    if warmup and not table.empty:
        at = table[table["update"] >= warmup]
        if not at.empty:
            r = at.iloc[0]
            paras.append(f"At the first update where pruning may act ({int(r['update'])}): rho = "
                         f"{r['Spearman rho'] or 'n/a'} over {int(r['complete trials'])} complete trials "
                         f"(threshold {min_rho}).")
    pruned = trials[trials["state"] == "PRUNED"]
    if len(pruned):
        rhos = pruned["prune_rho"].dropna() if "prune_rho" in pruned else pd.Series(dtype=float)
        steps = sorted(set(pruned["pruned_at_step"].dropna().astype(int)))
        paras.append(f"{len(pruned)} trial(s) pruned" + (f", at update(s) {steps}" if steps else "")
                     + (f"; rank correlation at the decision {rhos.min():.2f} to {rhos.max():.2f}" if len(rhos) else "")
                     + ".")
    if table.empty:
        paras.append("No intermediate value before the final one (or no complete trial yet).")
    return Section("Pruning: do intermediate values predict final ones?", paras,
                   None if table.empty else table)


def _points(trials: pd.DataFrame, replicates: int, names: list[str]) -> Section:
    table = point_table(trials, replicates)
    if table.empty:
        return Section("Configurations", ["No trial yet."])
    shown = table[[*names, "complete", "pruned", "failed"]].copy()
    shown["mean objective"] = table["value"].map(lambda v: _f(v, 4))
    shown["95% CI"] = [f"[{_f(lo, 4)}, {_f(hi, 4)}]" if pd.notna(lo) else "" for lo, hi in
                       zip(table["ci_low"], table["ci_high"], strict=True)]
    shown["success rate"] = table["success_rate"].map(_f)
    shown["team return"] = table["team_return"].map(lambda v: _f(v, 2))
    for key, label in RATE_LABELS.items():  # beside the success rate of a method with a filter
        if table[key].notna().any():
            shown[label] = table[key].map(_pct)
    shown["eligible"] = table["eligible"].map({True: "yes", False: "no"})
    shown["trials"] = table["trials"]
    return Section("Configurations (mean over replicates)", [
        f"Best first. Eligible: {replicates} complete replicates and none pruned."], shown)


def _trials(trials: pd.DataFrame, names: list[str]) -> Section:
    cols = ["number", "state", *names, "replicate", "seed", "value", "success_rate", "team_return",
            *FILTER_RATES, "last_step", "pruned_at_step", "prune_rho", "wall_s"]
    df = trials[[c for c in cols if c in trials and (c not in FILTER_RATES or trials[c].notna().any())]]
    df = df.sort_values("number").copy()
    for key in FILTER_RATES:
        if key in df:
            df[key] = df[key].map(_pct)
    for c, d in (("value", 4), ("success_rate", 3), ("team_return", 2), ("prune_rho", 2), ("wall_s", 1)):
        if c in df:
            df[c] = df[c].map(lambda v, d=d: _f(v, d))
    df = df.astype(object).where(df.notna(), "")
    return Section("Trials", [], df)


def _importances(imp: Mapping[str, Any]) -> Section:
    values = imp.get("importances") or {}
    if not values:
        return Section("Parameter importances", [f"Not computed: {imp.get('reason')}."])
    return Section("Parameter importances", [
        ", ".join(f"{k} {v:.2f}" for k, v in values.items()) + ".", str(imp.get("caveat") or "")])
