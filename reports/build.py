"""``build_report``: rebuild every figure, table and page of the report from the store alone.

The only function of ``reports`` that writes files. It reads the run's Parquet store
(``reports.data.store``), calls the pure builders and writes their outputs into
``<run>/report/`` (or ``bench report --out DIR``, e.g. for a read-only run folder), each
atomically (temp file + rename, permissions from the umask), so an interrupted rebuild
never leaves a half-written file; a full disk is one ``DiskFull`` line. Done cells whose
rows are incomplete (bench/store/completeness.py, the runner's rule) are listed among the
store's problems (reports/data/store.py).
Deterministic: bootstrap generators are seeded, so the same store gives the same numbers.

The generic report, for any run and any method, comes first: the leaderboard
(leaderboard.{md,csv}, its aggregates, safety_all_methods.csv, leaders.{md,csv},
success_vs_n, success_vs_p, performance_profiles), the learning curves of every learned
method (learning_curves), the robustness of training (robustness.{md,csv}), the summary
(summary.{md,csv}, success_by_mode.md, progress.md), every seed (seeds.{md,csv}), linked studies and the robustness
matrix (reports/matrix.py). Then each registered section that applies to the run
(``reports.sections``; e.g. the paper wing's Fig. 1-3, Table I, ablation and claims), and
index.md, index.html.
"""
from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from bench.store.study_files import CONFIG_FILE, LINK_KEY, REPORT_PAGES, report_files
from bench.store.study_files import REPORT_DIR as STUDY_REPORT_DIR
from envs.atomic import temp_target
from envs.errors import BenchError
from reports.data.against import merge_against
from reports.data.store import load_store
from reports.data.variants import cell_variants, default_rows
from reports.figures.learning_curves import learning_curves
from reports.figures.training_diagnostics import training_diagnostics
from reports.matrix import matrix_entries
from reports.pages.index import Entry, IndexData, index_html, index_markdown
from reports.sections import ReportContext, registered_sections
from reports.tables.leaderboard import (
    aggregate_frame,
    filter_note,
    leaderboard_display,
    leaderboard_frame,
    leaderboard_markdown,
    safety_frame,
    score_figures,
)
from reports.tables.leaders import (
    leaders_display,
    leaders_frame,
    leaders_markdown,
    per_method_display,
    per_method_frame,
)
from reports.tables.mapf import CAPTION as MAPF_CAPTION
from reports.tables.mapf import mapf_display, mapf_frame, mapf_markdown, tasks_of
from reports.tables.ordering import ordering_frame, ordering_markdown
from reports.tables.progress import progress_markdown
from reports.tables.robustness import (
    ROBUSTNESS_CAPTION,
    robustness_display,
    robustness_frame,
    robustness_markdown,
    seeds_frame,
    seeds_markdown,
)
from reports.tables.success_table import success_markdown
from reports.tables.summary import SUMMARY_CAPTION, SUMMARY_HEAD, summary_display, summary_frame, summary_markdown
from reports.writers import copy_file, save_figure, write_text

REPORT_DIR = "report"


def remove_stale_temp_files(out: Path) -> int:
    """Delete the temp files ('.<name>.<random>.tmp') an earlier report left when it was
    killed (SIGKILL, power loss) before its atomic writes could clean up; returns how many."""
    if not out.is_dir() or out.is_symlink():
        return 0
    stale = [p for p in out.rglob(".*") if p.is_file() and not p.is_symlink() and temp_target(p.name)]
    for p in stale:
        p.unlink(missing_ok=True)
    return len(stale)


HOW_TO_LINK = ("No study records this run. A study is linked when its studies/<name>/study.json "
               "(beside the run folder) holds \"run\": \"{run}\"; its report is then copied into "
               "this report's studies/<name>/ folder.")


def _study_entries(run_dir: Path, out: Path, problems: list[str] | None = None) -> tuple[list[Entry], str]:
    """Optuna studies launched for this run (``<run>/../studies/<name>/study.json`` naming
    the run folder under ``"run"``): the report ``bench tune`` built for each
    (``studies/<name>/report/``) is copied into ``<report>/studies/<name>/`` (links stay
    inside the report folder) and linked. Returns the entries and, when none is linked, a
    note saying how to link one. A study whose study.json cannot be read, or whose report
    was never built, is left out with a line in ``problems`` (it may be another run's: it
    never stops the report)."""
    from bench.store.meta_schema import StudyConfig, validated

    problems = problems if problems is not None else []
    entries = []
    run = run_dir.resolve()
    for cfg_path in sorted((run.parent / "studies").glob(f"*/{CONFIG_FILE}")):
        name = cfg_path.parent.name
        shown = f"studies/{name}"
        try:
            cfg = validated(StudyConfig, json.loads(cfg_path.read_text(encoding="utf-8")), cfg_path)
        except (OSError, ValueError, BenchError) as exc:
            why = str(exc) if isinstance(exc, BenchError) else " ".join(str(exc).split())[:160]
            problems.append(f"study {shown} beside the run was left out: its {CONFIG_FILE} is unreadable ({why})")
            continue
        if str(cfg.get(LINK_KEY, "")) not in (run.name, str(run)):
            continue
        built = cfg_path.parent / STUDY_REPORT_DIR
        files = [built / f for f in report_files() if (built / f).is_file()]
        if not any(f.name in REPORT_PAGES for f in files):
            problems.append(f"study {shown} was left out: it has no built report ({shown}/{STUDY_REPORT_DIR}/ "
                            "holds no study page; `bench tune` writes it when the study's trials finish)")
            continue
        rel = tuple(f"studies/{name}/{copy_file(f, out / 'studies' / name / f.name).name}" for f in files)
        image = next((r for r in rel if r.endswith("study_landscape.png")), None)
        entries.append(Entry(f"Study {name}: |R_z| x L (bench tune)",
                             tuple(r for r in rel if r.endswith((".html", ".md"))) + rel, image=image,
                             caption=f"Study {name}: tuning landscape (see its study page for trials and curves)."))
    return entries, "" if entries else HOW_TO_LINK.format(run=run.name)


def _shown_path(run_dir: Path) -> str:
    """The run directory as the index shows it: relative to the working directory when
    inside it (a committed report does not name the machine it was built on), else absolute."""
    run = run_dir.resolve()
    try:
        return str(run.relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(run)


def _leaderboard(evals: pd.DataFrame, out: Path) -> Entry:
    """The method-agnostic part of every report (reports/tables/leaderboard.py): every method of
    the run by its declared name, each configuration's default variant."""
    board = leaderboard_frame(evals)
    iqm, poi = aggregate_frame(evals)
    safety = safety_frame(evals)
    write_text(out / "leaderboard.md", leaderboard_markdown(board, iqm, poi, safety))
    write_text(out / "leaderboard.csv", board.to_csv(index=False))
    write_text(out / "leaderboard_aggregate.csv", iqm.to_csv(index=False))
    write_text(out / "leaderboard_improvement.csv", poi.to_csv(index=False))
    write_text(out / "safety_all_methods.csv", safety.to_csv(index=False))
    leaders = leaders_frame(evals)
    per_method = per_method_frame(evals, leaders)
    tasks = tasks_of(evals) or ["one-shot"]  # each raced by its own score (docs/decisions/0235)
    write_text(out / "leaders.md", leaders_markdown(leaders, per_method, tasks) + "\n"
               + ordering_markdown(ordering_frame(evals)))
    write_text(out / "leaders.csv", leaders.to_csv(index=False))
    files = ["leaderboard.md", "leaderboard.csv", "leaderboard_aggregate.csv", "leaderboard_improvement.csv",
             "safety_all_methods.csv", "leaders.md", "leaders.csv"]
    captions = []
    figures = score_figures(board, evals)  # each task's own score (docs/decisions/0235)
    for stem, built in figures:
        save_figure(built.fig, out / stem, built.caption)
        files += [f"{stem}.png", f"{stem}.pdf", f"{stem}.txt"]
        captions.append(built.caption)
    scores = {"one-shot": "Success rate", "lifelong": "Throughput (goals reached per step)"}
    owns = {"one-shot": ("success", "the two rates' logit t intervals"),
            "lifelong": ("throughput", "the two throughputs' Cox lognormal intervals")}
    own = owns[tasks[0]] if len(tasks) == 1 else (
        "score (success of one-shot cells, throughput of lifelong cells, each task apart)",
        "the two scores' intervals")
    score = (scores[tasks[0]] if len(tasks) == 1 else
             "Each task's own score, never one against the other: success rate of one-shot cells, throughput "
             "(goals reached per step) of lifelong cells,") + " per configuration and execution mode"
    tables = (("Per learned method and mode: how many of the configurations it shares with another "
               "learned method it leads (by a margin whose 95% CI over seeds excludes 0: the square-and-add "
               f"of {own[1]}), and its "
               f"{own[0]} minus the best planner's where one ran (range of the means; at how many the CI "
               "lies below / above 0). Details: leaders.md.", per_method_display(per_method)),
              (f"{score}: mean over seeds [95% CI over seeds] "
               "(rank among the methods); [interval not trusted] where the interval's simulated coverage is "
               "under 93% (seeds collapsed; docs/decisions/0233). Aggregates, pairwise probability of "
               "improvement and the safety "
               "columns of every method: leaderboard.md." + filter_note(board), leaderboard_display(board)),
              ("Who leads where: per configuration and learned mode, the leading learned method > or ≈ "
               "the runner-up (the margin's 95% CI over seeds, square-and-add, excludes 0, or not; "
               "pointwise). "
               "Counts and the distance to the planners: leaders.md.", leaders_display(leaders)))
    # a table without rows (no learned method, e.g. a planner-only run) is left out of the page
    return Entry("Leaderboard: every method of the run", tuple(files),
                 tables=tuple((caption, t) for caption, t in tables if len(t)),
                 image=f"{figures[0][0]}.png", caption=captions[0])


def _learning_curves(train: pd.DataFrame, out: Path) -> Entry:
    """Every learned method's training curve per configuration (reports/figures/learning_curves.py)."""
    built = learning_curves(train)
    save_figure(built.fig, out / "learning_curves", built.caption)
    return Entry("Learning curves: every learned method of the run",
                 ("learning_curves.png", "learning_curves.pdf", "learning_curves.txt"), tuple(built.notes),
                 image="learning_curves.png", caption=built.caption)


def _training_diagnostics(train: pd.DataFrame, out: Path) -> list[Entry]:
    """Runs whose train rows hold the diagnostics (docs/decisions/0200): their figure."""
    diag = training_diagnostics(train)
    if diag is None:
        return []
    save_figure(diag.fig, out / "training_diagnostics", diag.caption)
    return [Entry("Training diagnostics", ("training_diagnostics.png", "training_diagnostics.pdf",
                                           "training_diagnostics.txt"), tuple(diag.notes),
                  image="training_diagnostics.png", caption=diag.caption)]


def _robustness(train: pd.DataFrame, evals: pd.DataFrame, variants: pd.Series, out: Path) -> Entry:
    """Collapsed seeds and falling returns per learned method, variant and N, and every
    seed's success (reports/tables/robustness.py); every variant in its own rows."""
    frame = robustness_frame(train, evals, variants)
    write_text(out / "robustness.md", robustness_markdown(frame))
    write_text(out / "robustness.csv", frame.to_csv(index=False))
    seeds = seeds_frame(train, evals, variants)
    write_text(out / "seeds.md", seeds_markdown(seeds))
    write_text(out / "seeds.csv", seeds.to_csv(index=False))
    return Entry("Robustness of training", ("robustness.md", "robustness.csv", "seeds.md", "seeds.csv"),
                 tables=((ROBUSTNESS_CAPTION, robustness_display(frame)),) if len(frame) else ())


def _summary(evals: pd.DataFrame, cells: pd.DataFrame, out: Path) -> Entry:
    """Every configuration and variant (reports/tables/summary.py) and the README's tables."""
    write_text(out / "progress.md", progress_markdown(cells))  # the README's status table
    summary = summary_frame(evals, cells)
    write_text(out / "summary.md", summary_markdown(summary))
    write_text(out / "summary.csv", summary.to_csv(index=False))
    write_text(out / "success_by_mode.md", success_markdown(summary, cells))  # the README's results table
    shown = summary_display(summary)
    keys, ci_over = SUMMARY_HEAD[:4], SUMMARY_HEAD[-1:]
    # Two tables of the same rows: all 14 columns did not fit a 1400 px window.
    tables = (("Summary of every configuration: success and return. " + SUMMARY_CAPTION,
               shown[keys + SUMMARY_HEAD[4:10] + ci_over]),
              ("Summary of every configuration, continued: collisions, corrections, fallbacks and payload, "
               "the same rows (mean over seeds [95% CI]; n/a: the method has no safety filter).",
               shown[keys + SUMMARY_HEAD[10:]]))
    return Entry("Summary of every configuration (method x N x p x execution mode)",
                 ("summary.md", "summary.csv", "success_by_mode.md", "progress.md"), tables=tables)


def _mapf(evals: pd.DataFrame, cells: pd.DataFrame, out: Path) -> list[Entry]:
    """The MAPF metrics (reports/tables/mapf.py), only for a store whose eval rows hold them."""
    frame = mapf_frame(evals, cells)
    if frame.empty:
        return []
    write_text(out / "mapf.md", mapf_markdown(frame))
    write_text(out / "mapf.csv", frame.to_csv(index=False))
    return [Entry("MAPF metrics: CSR, sum of costs, makespan; throughput of lifelong tasks",
                  ("mapf.md", "mapf.csv"), tables=((MAPF_CAPTION, mapf_display(frame)),))]


def build_report(run_dir: Path | str, out_dir: Path | str | None = None, claims_at: str = "paper",
                 against: Path | str | None = None) -> Path:
    """Rebuild the report (default ``<run_dir>/report/``, else ``out_dir``) from the store;
    returns that directory (holding ``index.html``). Missing, failed or incomplete cells are
    listed, never fatal; a run directory without ``cells.parquet`` is a ``BenchError``.
    ``claims_at="run"`` also checks the claims at the run's own configurations. ``against``:
    a second run whose done cells at this run's configurations join the report
    (reports/data/against.py: refused unless settings and scenarios match)."""
    store = load_store(run_dir)
    out = Path(out_dir) if out_dir is not None else Path(run_dir) / REPORT_DIR
    remove_stale_temp_files(out)
    if against is not None:
        store = merge_against(store, against)
    # Figures, Table I and the claims: each group's default variant only (reports.data.variants);
    # the summary and the success table show every variant in its own row.
    variants = cell_variants(store.cells)
    train, evals = default_rows(store.train, variants), default_rows(store.eval, variants)
    default_cells = default_rows(store.cells, variants)
    if len(default_cells) < len(store.cells):
        store.problems.append(
            f"{len(store.cells) - len(default_cells)} cells are variants of their configuration "
            "(reports/data/variants.py): they have their own rows in the summary and success tables "
            "and are left out of the figures, Table I and the claims")
    entries = [_leaderboard(evals, out), _learning_curves(train, out), *_training_diagnostics(train, out),
               _robustness(store.train, store.eval, variants, out), _summary(store.eval, store.cells, out),
               *_mapf(store.eval, store.cells, out)]
    studies, studies_note = _study_entries(Path(run_dir), out, store.problems)
    entries += studies
    entries += matrix_entries(run_dir, out)  # RUN/matrix/ (bench matrix)

    # Replays written by `bench replay` (default RUN/replays/) are copied into the report
    # folder, so its links stay inside it.
    kinds = ("*.gif", "*.mp4")
    for clip in sorted(c for k in kinds for c in (Path(run_dir) / "replays").glob(k)):
        if clip.resolve().parent != (out / "replays").resolve():
            copy_file(clip, out / "replays" / clip.name)
    replays = sorted(str(p.relative_to(out)) for k in kinds for p in out.glob(f"replays/{k}"))
    ctx = ReportContext(Path(run_dir), out, store, train, evals, default_cells, {"claims_at": claims_at})
    parts = [section.build(ctx) for section in registered_sections() if section.applies(ctx)]
    data = IndexData(_shown_path(Path(run_dir)), store.manifest, store.cells, entries, parts,
                     store.problems, replays, studies_note)
    write_text(out / "index.md", index_markdown(data))
    write_text(out / "index.html", index_html(data))
    return out
