"""The paper's sections of a run's report: Fig. 1-3, Table I, the ablation and the claims.

Registered with the harness in the entry-point group ``warehouse_marl_bench.report_sections``
(pyproject.toml), the way an outside package adds sections (``reports.sections``): the
generic report comes first for any run, and these follow only when the run has one of the
paper's methods (``paper.roles``), each figure only when the run has cells of the methods
it draws (a figure whose cells are not done yet shows placeholders).

Files: fig1_training, fig2_success_percentiles (the run's first execution mode) and
fig2_success_percentiles_<mode> for each other mode, fig3_comm_payload (.png, .pdf, .txt),
table1_safety.{md,tex,csv}, ablation.{md,csv} (runs of the ablation grid),
claims.{md,csv}, claims_table.md (the README's table) and calibration.{json,md}.
"""
from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from paper.claims.catalog import all_claims
from paper.claims.method_claims import method_claims
from paper.claims.page import calibration_markdown, claims_frame, claims_markdown, claims_table_markdown
from paper.figures.fig1_training import fig1_training
from paper.figures.fig2_success import fig2_modes, fig2_success
from paper.figures.fig3_payload import fig3_payload
from paper.pages.front import ClaimsFront
from paper.roles import FIG1_METHODS, FIG2_METHODS, FIG3_METHODS, REFERENCE_METHOD, has_role
from paper.tables.ablation import ablation_frame, ablation_markdown, component_values, setting
from paper.tables.table1_safety import table1_caption, table1_display, table1_frame, table1_latex, table1_markdown
from reports.figures.plotting import Built
from reports.pages.index import Entry, markdown_tables
from reports.sections import ReportContext, SectionOutput
from reports.tables.summary import ci_display
from reports.writers import copy_file, save_figure, write_text

__all__ = ["PaperSections"]

TITLE = "The paper's reproduction (Sec. IV)"
ABLATION_LABELS = {"variant": "variant", "seeds": "seeds", "eval_episodes": "eval episodes", "departs": "departs from"}
ABLATION_METRICS = {"success_rate": ("success rate", "pct"), "collision_rate": ("collision rate", "pct"),
                    "correction_rate": ("correction rate", "pct"), "fallback_rate": ("fallback rate", "pct"),
                    "payload_scalars_per_step": ("payload (scalars/step)", "payload")}
CALIBRATION = Path(__file__).parent / "claims" / "calibration.json"  # the paper run's, `bench calibrate --out`


def mode_slug(mode: str) -> str:
    """A file-name part for an execution mode: "sample@0.5" -> "sample_at_0p5" (no dot, so
    ``Path.with_suffix`` keeps it)."""
    return "".join(c if c.isalnum() else {"@": "_at_", ".": "p"}.get(c, "_") for c in mode)


def _calibration(out: Path, run_dir: Path) -> tuple[str | None, bool]:
    """``calibration.md`` from ``<report>/calibration.json`` (``bench calibrate --run RUN
    --out``; a report written elsewhere with ``--out`` takes the run's own
    ``RUN/report/calibration.json``; never another run's: docs/decisions/0230); returns its
    name for the claims page (None without a table) and whether its ``meta.run`` is this run."""
    cached = out / "calibration.json"
    own = Path(run_dir) / "report" / "calibration.json"  # the run's own table, when --out writes elsewhere
    if not cached.exists() and own.is_file() and own.resolve() != cached.resolve():
        copy_file(own, cached)
    if not cached.exists():
        return None, False
    rep = json.loads(cached.read_text(encoding="utf-8"))
    write_text(out / "calibration.md", calibration_markdown(pd.DataFrame(rep["calibration"]), rep.get("meta"),
                                                           pd.DataFrame(rep.get("coverage", []))))
    return "calibration.md", is_own(rep.get("meta", {}).get("run", ""), run_dir)


def is_own(meta_run: str, run_dir: Path) -> bool:
    """Whether a calibration's ``meta.run`` names ``run_dir`` (the same path, or its tail)."""
    if not meta_run:
        return False
    tail = Path(meta_run).parts
    return Path(run_dir).resolve().parts[-len(tail):] == tail


def _figure(stem: str, title: str, built: Built, out: Path) -> Entry:
    save_figure(built.fig, out / stem, built.caption)
    return Entry(title, (f"{stem}.png", f"{stem}.pdf", f"{stem}.txt"), tuple(built.notes),
                 image=f"{stem}.png", caption=built.caption)


def _has(run_methods: set[str], methods: tuple[str, ...]) -> bool:
    """Whether the run has a cell of any of ``methods`` (the ones a figure draws)."""
    return bool(run_methods & set(methods))


class PaperSections:
    """``reports.sections.ReportSections`` for the paper."""

    def applies(self, ctx: ReportContext) -> bool:
        """The run has one of the paper's methods (its own method or a baseline it names)."""
        return any(has_role(m) for m in ctx.methods)

    def build(self, ctx: ReportContext) -> SectionOutput:
        train, evals, out = ctx.train, ctx.evals, ctx.out
        entries: list[Entry] = []
        run = ctx.methods
        if _has(run, FIG1_METHODS):
            entries.append(_figure("fig1_training", "Fig. 1: training convergence", fig1_training(train), out))
        if _has(run, FIG2_METHODS):
            for k, m in enumerate(fig2_modes(evals)):  # one figure per execution mode, the first under its CI name
                entries.append(_figure("fig2_success_percentiles" + ("" if k == 0 else "_" + mode_slug(m)),
                                       f"Fig. 2: success-rate percentile curves vs IC3Net ({m} execution)",
                                       fig2_success(evals, m), out))
        if _has(run, FIG3_METHODS):
            entries.append(_figure("fig3_comm_payload", "Fig. 3: communication payload and ratio",
                                   fig3_payload(evals), out))
        if _has(run, (REFERENCE_METHOD,)):
            entries.append(self._table1(evals, out))
        entries += self._ablation(ctx)
        at = ctx.options.get("claims_at", "paper")
        claims = all_claims(train, evals, at=at, cells=ctx.cells) + method_claims(evals)
        front = ClaimsFront(claims)
        cal, own = _calibration(out, ctx.run_dir)
        write_text(out / "claims.md", claims_markdown(claims, cal, own))
        write_text(out / "claims_table.md", claims_table_markdown(claims))  # the README's table
        checks = claims_frame(claims)
        write_text(out / "claims.csv", checks.to_csv(index=False))
        cal_tables = markdown_tables((out / cal).read_text(encoding="utf-8"), (
            "Calibration of the claim tests: rate of 'supported' on simulated data where the claim is "
            "false (null, must be <= 5% + MC error) or true (effect: the power)")) if cal else []
        files = ("claims.md", "claims.csv", "claims_table.md") + ((cal,) if cal else ())
        entries.append(Entry("Claims of Sec. IV", files, tables=tuple(cal_tables),
                             html_block=front.checks_block(checks)))
        return SectionOutput(TITLE, entries, front)

    @staticmethod
    def _table1(evals: pd.DataFrame, out: Path) -> Entry:
        table, t_notes = table1_frame(evals)
        write_text(out / "table1_safety.md", table1_markdown(table, t_notes))
        write_text(out / "table1_safety.tex", table1_latex(table))
        write_text(out / "table1_safety.csv", table.to_csv(index=False))
        modes = list(dict.fromkeys(table["execution"])) if len(table) else []
        return Entry("Table I: safety filter, per execution mode",
                     ("table1_safety.md", "table1_safety.tex", "table1_safety.csv"), tuple(t_notes),
                     tables=tuple((f"Table I ({m}). " + table1_caption(table, m), table1_display(table, m))
                                  for m in modes))

    @staticmethod
    def _ablation(ctx: ReportContext) -> list[Entry]:
        store, out = ctx.store, ctx.out
        ablation = ablation_frame(store.eval, store.cells)
        if not len(ablation):  # only runs of the ablation grid
            return []
        write_text(out / "ablation.md", ablation_markdown(ablation, component_values(store.eval, store.cells),
                                                          setting(store.cells)))
        write_text(out / "ablation.csv", ablation.to_csv(index=False))
        return [Entry("Ablation of the hierarchical method", ("ablation.md", "ablation.csv"),
                      tables=tuple((f"Ablation, {mode} execution: mean over seeds [95% CI over {g['ci_over'].iloc[0]}]",
                                    ci_display(g, ABLATION_LABELS, ABLATION_METRICS))
                                   for mode, g in ablation.groupby("execution", sort=False)))]
