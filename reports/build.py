"""``build_report``: rebuild every figure, table and page of the report from the store alone.

The only function of ``reports`` that writes files. It reads the run's Parquet store
(``reports.store``), calls the pure builders (figures, Table I, summary, claims, index)
and writes their outputs into ``<run>/report/`` (or ``bench report --out DIR``, e.g. for
a read-only run folder), each atomically (temp file + rename, permissions from the
umask), so an interrupted rebuild never leaves a half-written file; a full disk is one
``DiskFull`` line. Done cells whose rows are incomplete (bench/completeness.py) are
listed among the store's problems. Deterministic: bootstrap
generators are seeded, so the same store gives the same numbers.

Outputs: fig1_training, fig2_success_percentiles, fig3_comm_payload (.png at 200 dpi and
.pdf), table1_safety.{md,tex,csv}, summary.{md,csv}, claims.{md,csv}, calibration.{json,md} (the
calibration of the claim tests), matrix_*.png/.pdf and matrix.{md,csv} when RUN/matrix/ exists
(reports/matrix.py), index.md, index.html.
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

from matplotlib.figure import Figure

from bench.completeness import incomplete_cells
from bench.store import DiskFull, RunStore, file_mode, is_disk_full
from reports.ablation import ablation_frame, ablation_markdown, component_values, setting
from reports.claims import all_claims
from reports.claims_page import calibration_markdown, claims_frame, claims_markdown
from reports.fig1_training import fig1_training
from reports.fig2_success import fig2_success
from reports.fig3_payload import fig3_payload
from reports.index import Entry, IndexData, index_html, index_markdown
from reports.matrix import matrix_entries
from reports.plotting import DPI
from reports.store import load_store
from reports.summary import summary_frame, summary_markdown
from reports.table1_safety import table1_frame, table1_latex, table1_markdown

REPORT_DIR = "report"
FIGURES = ("fig1_training", "fig2_success_percentiles", "fig3_comm_payload")


def _atomic(path: Path, write: Callable[[str], None]) -> Path:
    """Call ``write(tmp)`` on a temp file next to ``path``, then rename it into place."""
    tmp = ""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        os.close(fd)
        write(tmp)
        os.chmod(tmp, file_mode())  # mkstemp creates 0600; a report follows the umask like any file
        os.replace(tmp, path)
    except BaseException as exc:
        if tmp:
            Path(tmp).unlink(missing_ok=True)
        if is_disk_full(exc):
            raise DiskFull(path) from None
        raise
    return path


def write_text(path: Path, text: str) -> Path:
    return _atomic(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def save_figure(fig: Figure, stem: Path) -> list[Path]:
    """``stem``.png (200 dpi) and ``stem``.pdf."""
    return [_atomic(stem.with_suffix(f".{fmt}"),
                    lambda tmp, fmt=fmt: fig.savefig(tmp, format=fmt, dpi=DPI))
            for fmt in ("png", "pdf")]


def _study_entries(run_dir: Path, out: Path) -> list[Entry]:
    """Optuna studies beside the run (``<run>/../studies/<name>/trials.parquet``, where
    ``bench tune`` exports them): their reports are rebuilt and linked from the index
    (optimization history, the L x |R_z| landscape, parameter importances)."""
    from studies.export import TRIALS_FILE
    from studies.report import build_study_report

    entries = []
    for trials in sorted((run_dir.resolve().parent / "studies").glob(f"*/{TRIALS_FILE}")):
        files = build_study_report(trials.parent)
        rel = tuple(os.path.relpath(f, out) for f in files
                    if f.suffix in (".md", ".png"))
        image = next((r for r in rel if r.endswith("study_landscape.png")), None)
        entries.append(Entry(f"Study {trials.parent.name}: |R_z| x L (bench tune)", rel, image=image))
    return entries


CALIBRATION = Path(__file__).with_name("calibration.json")  # `bench calibrate --out`, committed


def _calibration(out: Path) -> str | None:
    """``calibration.md`` from ``<report>/calibration.json`` (copied from the packaged
    table when absent); returns its name for the claims page, None without a table."""
    cached = out / "calibration.json"
    if not cached.exists() and CALIBRATION.exists():
        _atomic(cached, lambda tmp: shutil.copyfile(CALIBRATION, tmp))
    if not cached.exists():
        return None
    rep = json.loads(cached.read_text(encoding="utf-8"))
    import pandas as pd

    write_text(out / "calibration.md", calibration_markdown(pd.DataFrame(rep["calibration"]), rep.get("meta")))
    return "calibration.md"


def build_report(run_dir: Path | str, out_dir: Path | str | None = None, claims_at: str = "paper") -> Path:
    """Rebuild the report (default ``<run_dir>/report/``, else ``out_dir``) from the store;
    returns that directory (holding ``index.html``). Missing, failed or incomplete cells are
    listed, never fatal; a run directory without ``cells.parquet`` is a ``BenchError``.
    ``claims_at="run"`` also checks the claims at the run's own configurations."""
    store = load_store(run_dir)
    out = Path(out_dir) if out_dir is not None else Path(run_dir) / REPORT_DIR
    for cid, gap in incomplete_cells(RunStore(run_dir), store.cells).items():
        store.problems.append(f"cell {cid} is done but its rows are incomplete: {gap}")
    train, evals = store.train, store.eval
    entries: list[Entry] = []

    titles = {
        "fig1_training": "Fig. 1: training convergence",
        "fig2_success_percentiles": "Fig. 2: success-rate percentile curves vs IC3Net, per execution mode",
        "fig3_comm_payload": "Fig. 3: communication payload and ratio",
    }
    builders = {"fig1_training": lambda: fig1_training(train),
                "fig2_success_percentiles": lambda: fig2_success(evals),
                "fig3_comm_payload": lambda: fig3_payload(evals)}
    for stem in FIGURES:
        built = builders[stem]()
        save_figure(built.fig, out / stem)
        entries.append(Entry(titles[stem], (f"{stem}.png", f"{stem}.pdf"), tuple(built.notes),
                             image=f"{stem}.png"))

    table, t_notes = table1_frame(evals)
    write_text(out / "table1_safety.md", table1_markdown(table, t_notes))
    write_text(out / "table1_safety.tex", table1_latex(table))
    write_text(out / "table1_safety.csv", table.to_csv(index=False))
    entries.append(Entry("Table I: safety filter, per execution mode",
                         ("table1_safety.md", "table1_safety.tex", "table1_safety.csv"), tuple(t_notes)))

    summary = summary_frame(evals, store.cells)
    write_text(out / "summary.md", summary_markdown(summary))
    write_text(out / "summary.csv", summary.to_csv(index=False))
    entries.append(Entry("Summary of every configuration (method x N x p x execution mode)",
                         ("summary.md", "summary.csv")))

    ablation = ablation_frame(evals, store.cells)
    if len(ablation):  # runs of the ablation grid
        write_text(out / "ablation.md", ablation_markdown(
            ablation, component_values(evals, store.cells), setting(store.cells)))
        write_text(out / "ablation.csv", ablation.to_csv(index=False))
        entries.append(Entry("Ablation of the hierarchical method", ("ablation.md", "ablation.csv")))

    claims = all_claims(train, evals, at=claims_at, cells=store.cells)
    cal = _calibration(out)
    write_text(out / "claims.md", claims_markdown(claims, cal))
    write_text(out / "claims.csv", claims_frame(claims).to_csv(index=False))
    entries.append(Entry("Claims of Sec. IV", ("claims.md", "claims.csv") + ((cal,) if cal else ())))

    entries += _study_entries(Path(run_dir), out)
    entries += matrix_entries(run_dir, out, save_figure, write_text)  # RUN/matrix/ (bench matrix)

    # GIFs written by `bench replay` (default RUN/replays/) or into the report folder.
    replays = sorted(os.path.relpath(p, out) for p in (Path(run_dir) / "replays").glob("*.gif"))
    replays += sorted(str(p.relative_to(out)) for p in out.glob("replays/*.gif"))
    data = IndexData(str(Path(run_dir).resolve()), store.manifest, store.cells, entries, claims,
                     store.problems, replays)
    write_text(out / "index.md", index_markdown(data))
    write_text(out / "index.html", index_html(data))
    return out
