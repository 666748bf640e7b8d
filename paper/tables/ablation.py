"""The ablation of the hierarchical method (``bench run --grid ablation``).

Every done cell of the ``ablation`` grid (the ``grid`` column of cells.parquet; other
grids' cells are never pooled in) is matched to a variant of
``paper.grids.ABLATION_VARIANTS`` by its method, |R_z| and the hyperparameters that define
variants (other hyperparameters, such as batch sizes, are ignored). Per variant: success rate, collision rate,
correction rate,
fallback rate and payload (scalars per step), each the mean over seeds of the per-seed
evaluation mean with a 95% Student t CI over seeds (over evaluation episodes when a
variant has one seed, as in the summary), separately per execution mode (modes are never
pooled; PIBT-style planner rows do not occur here). Then one sentence per component and
mode: the difference in success rate between the two variants that isolate it, with a
95% Welch t CI over seeds (the seed is the unit, reports/stats.py), and what that says;
fewer than 3 seeds on an arm gives no verdict (the claims' rule). Runs without ablation
variants give an empty frame (no section).
"""
from __future__ import annotations

import json
from typing import Any

import numpy as np
import pandas as pd

from algorithms.registry import find_method
from paper.grids import ABLATION_VARIANTS, Variant
from reports.data.store import execution_order, fmt_pct
from reports.stats import t_test
from reports.tables.summary import metric_estimate

METRICS = ("success_rate", "collision_rate", "correction_rate", "fallback_rate", "payload_scalars_per_step")
HEADERS = ("success rate", "collision rate", "correction rate", "fallback rate", "payload (scalars/step)")
VARIANT_KEYS = frozenset(k for v in ABLATION_VARIANTS for k in v.params)

# (component, with, without): success(with) - success(without) is what the component is worth.
COMPONENTS = (
    ("the GRU predictor (vs the last received message)", "paper", "last-received messages"),
    ("perfect prediction (oracle vs the GRU: the predictor's remaining gap)", "oracle messages", "paper"),
    ("the reference layer (|R_z| = 8 vs 1)", "paper", "no reference"),
    ("a held reference without entropy bonus (vs the paper's per-step r)", "held reference", "paper"),
    ("per-group parameters (vs shared)", "paper", "shared parameters"),
    ("the joint-Wait fallback (vs per-robot)", "paper", "per-robot fallback"),
    ("resampling a fallen-back group at execution", "resample on fallback", "paper"),
    ("the hierarchy as a whole (vs the decentralized baseline)", "paper", "decentralized"),
)


def _defaults(method: str) -> dict[str, Any]:
    cls = find_method(method)
    fields = cls.Params.model_fields if cls is not None else {}
    return {k: fields[k].default for k in VARIANT_KEYS if k in fields}


def variant_of(method: str, ref_size: int, params_json: str | None) -> Variant | None:
    """The ablation variant a cell belongs to, or None. ``params_json`` may hold only the
    overrides (a grid's spec) or every resolved hyperparameter (cells.parquet): a key that
    defines variants must equal the variant's value, or the method's default if the
    variant does not set it."""
    if find_method(method) is None:
        return None
    params = json.loads(params_json) if params_json else {}
    defaults = _defaults(method)
    for v in ABLATION_VARIANTS:
        if v.method != method or int(ref_size) != v.ref_size:
            continue
        want = {**defaults, **v.params}
        if all(params.get(k, defaults.get(k)) == want.get(k) for k in VARIANT_KEYS if k in want):
            return v
    return None


def label_cells(evals: pd.DataFrame, cells: pd.DataFrame) -> pd.DataFrame:
    """``evals`` rows of ablation cells with a ``variant`` column (label)."""
    mine = cells[cells["grid"] == "ablation"] if "grid" in cells else cells.iloc[:0]
    labels = {row.cell_id: (v.label if (v := variant_of(row.method, row.ref_size, row.params_json)) else None)
              for row in mine.itertuples()}
    out = evals.assign(variant=evals["cell_id"].map(labels))
    return out[out["variant"].notna()]


def ablation_frame(evals: pd.DataFrame, cells: pd.DataFrame) -> pd.DataFrame:
    """One row per variant present: seeds, evaluation episodes, and (mean, lo, hi) of each
    metric; variants in the order of ``ABLATION_VARIANTS``."""
    rows = label_cells(evals, cells)
    out = []
    for mode, by_mode in _by_mode(rows):
        for v in ABLATION_VARIANTS:
            r = by_mode[by_mode["variant"] == v.label]
            if r.empty:
                continue
            rec: dict[str, Any] = {"execution": mode, "variant": v.label, "method": v.method,
                                      "departs": v.departs, "seeds": r["cell_id"].nunique(),
                                      "eval_episodes": len(r)}
            for m in METRICS:
                mean, lo, hi, unit = metric_estimate(r, m)
                rec[m], rec[f"{m}_lo"], rec[f"{m}_hi"] = mean, lo, hi
                rec["ci_over"] = unit
            out.append(rec)
    return pd.DataFrame(out)


def _by_mode(rows: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    """(mode, rows) per execution mode in report order; a store without the column is one
    mode, 'argmax' (the bench's default before every mode was evaluated)."""
    if "execution" not in rows:
        return [("argmax", rows)] if len(rows) else []
    return [(m, rows[rows["execution"] == m]) for m in execution_order(rows["execution"].unique())]


def component_values(evals: pd.DataFrame, cells: pd.DataFrame) -> list[dict[str, Any]]:
    """Per execution mode and component present in the run: success(with) -
    success(without) in points, with a 95% Welch t CI over seeds (per-seed means)."""
    out = []
    for mode, rows in _by_mode(label_cells(evals, cells)):
        per_seed = rows.groupby(["variant", "cell_id"])["success_rate"].mean()
        present = set(per_seed.index.get_level_values(0))
        for name, with_, without in COMPONENTS:
            if with_ not in present or without not in present:
                continue
            a, b = per_seed[with_].to_numpy(), per_seed[without].to_numpy()
            t = t_test([a, b], [1.0, -1.0])
            out.append({"execution": mode, "component": name, "with": with_, "without": without,
                        "delta": float(a.mean() - b.mean()), "lo": t.lo, "hi": t.hi,
                        "seeds": (len(a), len(b))})
    return out


def _cell(v: float, lo: float, hi: float, pct: bool) -> str:
    if not np.isfinite(v):
        return "—"
    f = (lambda x: fmt_pct(x, 1) + "%") if pct else (lambda x: f"{x:.4g}")
    return f"{f(v)} [{f(lo)}, {f(hi)}]" if np.isfinite(lo) else f(v)


def _sentence(c: dict[str, Any]) -> str:
    d, lo, hi = (100 * float(c[k]) for k in ("delta", "lo", "hi"))
    n_a, n_b = c["seeds"]
    span = f" [{lo:+.1f}, {hi:+.1f}]" if np.isfinite(lo) else ""
    if min(n_a, n_b) < 3:
        verdict = "fewer than 3 seeds on an arm: no verdict"
    else:
        verdict = ("worth it: the CI lies above zero" if lo > 0 else
                   "harmful here: the CI lies below zero" if hi < 0 else
                   "not distinguishable from zero at this budget")
    return (f"- **{c['component']}** ({c['execution']}): success {d:+.1f} points{span} "
            f"(`{c['with']}` minus `{c['without']}`, {n_a} vs {n_b} seeds): {verdict}.")


def setting(cells: pd.DataFrame) -> str:
    """The configuration the ablation cells share, as one line (N, p, layout, budgets)."""
    mine = cells[cells["grid"] == "ablation"] if "grid" in cells else cells.iloc[:0]
    parts = []
    for col, name in (("n_robots", "N"), ("loss_p", "p"), ("layout", "layout"), ("episodes", "training episodes"),
                      ("horizon", "horizon"), ("eval_episodes", "evaluation episodes")):
        vals = sorted({str(v) for v in mine[col]}) if col in mine else []
        parts.append(f"{name} = {', '.join(vals) if vals else '?'}")
    return "; ".join(parts)


def ablation_markdown(frame: pd.DataFrame, components: list[dict[str, Any]], where: str = "") -> str:
    unit = frame["ci_over"].iloc[0] if len(frame) else "seeds"
    lines = ["# Ablation of the hierarchical method", "", *([f"Setting: {where}.", ""] if where else []),
             "Each variant changes one design choice of the paper's method (the `departs` column "
             "names the paper line); `decentralized` is the baseline. Mean over seeds of the "
             f"per-seed evaluation mean, [95% Student t CI over {unit}], one table per execution "
             "mode (every mode on the same evaluation scenarios). The summary gives each variant "
             "a row of its own; the figures, Table I and the claims of this run use the default "
             "variant of each configuration only (variants are never pooled as seeds)."]
    modes = list(dict.fromkeys(frame["execution"])) if len(frame) else []
    for mode in modes:
        lines += ["", f"### Execution: {mode}", "",
                  "| variant | seeds | eval episodes | " + " | ".join(HEADERS) + " | departs from |",
                  "|" + "---|" * (len(HEADERS) + 4)]
        for r in frame[frame["execution"] == mode].itertuples(index=False):
            rec = r._asdict()
            vals = [_cell(rec[m], rec[f"{m}_lo"], rec[f"{m}_hi"], m != "payload_scalars_per_step")
                    for m in METRICS]
            lines.append(f"| {rec['variant']} | {rec['seeds']} | {rec['eval_episodes']} | "
                         + " | ".join(vals) + f" | {rec['departs']} |")
    lines += ["", "## What each component is worth (success rate)", ""]
    lines += [_sentence(c) for c in components] or ["- no pair of variants isolating a component is in this run."]
    return "\n".join(lines) + "\n"
