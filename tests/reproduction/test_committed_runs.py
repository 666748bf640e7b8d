"""The committed reproduction runs: what is in git is what the current code means.

``reproduction/paper`` is the ``paper`` grid, ``reproduction/ablation`` the ``ablation`` grid and
``reproduction/full`` the ``full`` grid, run part-way across sessions. Every cell they hold must still be a cell of
today's grid definition (same cell_id: a changed default or setting would silently orphan the
committed rows), every done cell must have all its rows (training rows, and evaluation rows in
every execution mode, episode by episode), and a cell that is not done must have its
checkpoint committed so that a fresh clone resumes it. The committed report/ of each run is
what ``bench report`` on the current code rebuilds from its tables (the claims page byte for
byte), so a stale report or one built by other code cannot stay committed.
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from bench.design.grids import default_seeds, grid_builders
from bench.execute.plan import params_changes
from bench.store.completeness import incomplete_cells
from bench.store.run_store import RunStore

ROOT = Path(__file__).resolve().parents[2] / "reproduction"
RUNS = [name for name in ("paper", "ablation", "full") if (ROOT / name / "cells.parquet").is_file()]
# The full grid's report is committed once the run has finished; paper and
# ablation must always have theirs.
REPORTED = [name for name in RUNS if name != "full" or (ROOT / name / "report").is_dir()]
# Runs from grid files of their own (reproduction/<name>.toml) whose report is committed, each
# with the run its report is built --against (None: none): a rebuild must give it too.
GRID_FILE_REPORTS = {"probe-mappo": "full", "lifelong": None, "tuned-n40": None, "tuned-n40-480": None}


@pytest.fixture(params=RUNS)
def run(request: pytest.FixtureRequest) -> tuple[str, RunStore, pd.DataFrame]:
    store = RunStore(ROOT / request.param)
    return request.param, store, store.read_cells()


def test_reproduction__the_paper_run_is_committed() -> None:
    assert "paper" in RUNS, "reproduction/paper/cells.parquet is missing"


def todays_cells(name: str) -> dict:
    """cell_id -> cell of what runs into reproduction/<name>: the ``name`` grid at its default
    seeds, and the committed grid files of that grid name (reproduction/*.toml, e.g. the
    Fig. 1(a) seeds 3-4, which share the paper grid's cell ids for those seeds)."""
    from bench.design.grid_files import load_grid_file

    cells = {c.cell_id: c for c in grid_builders()[name](seeds=default_seeds(name)).cells}
    for path in sorted(ROOT.glob("*.toml")):
        grid = load_grid_file(path)
        if grid.name == name:
            cells.update((c.cell_id, c) for c in grid.cells)
    return cells


def test_committed_cells__are_cells_of_todays_grid(run) -> None:
    name, _, cells = run
    unknown = set(cells["cell_id"]) - set(todays_cells(name))
    assert not unknown, f"reproduction/{name}: cells no longer in the {name} grid: {sorted(unknown)}"


def test_committed_cells__ran_with_the_parameters_todays_code_resolves(run) -> None:
    """A cell id hashes overrides, not defaults: a default changed since a committed cell
    was trained leaves its id unchanged, so the rows would claim parameters they did not
    run with (IC3Net's action path, 2026-12-02). `bench run --rerun-changed` retrains them."""
    name, store, cells = run
    grid = todays_cells(name)
    stale = {row.cell_id: diff for row in cells.itertuples() if row.cell_id in grid and store.has_results(row.cell_id)
             and (diff := params_changes(str(row.params_json), grid[row.cell_id]))}
    assert not stale, f"reproduction/{name}: cells trained with other parameters than today's: {stale}"


def test_committed_done_cells__have_every_row_in_every_mode(run) -> None:
    name, store, cells = run
    assert (cells["status"] != "failed").all(), f"reproduction/{name}: failed cells committed"
    assert incomplete_cells(store, cells) == {}
    done = cells[cells["status"] == "done"]
    ev = store.read_eval()
    for row in done.itertuples():
        per_mode = ev[ev["cell_id"] == row.cell_id].groupby("execution")["episode"].apply(set).to_dict()
        want = {mode: set(range(row.eval_episodes)) for mode in row.executions.split(",")}
        assert per_mode == want, f"reproduction/{name}: {row.cell_id} ({row.method}) eval rows per mode"


def missing_cells(name: str, cells: pd.DataFrame) -> list[str]:
    """Cells of the ``name`` grid (its default seeds, at least 3) not committed as done."""
    grid = grid_builders()[name](seeds=max(3, default_seeds(name)))
    done = set(cells.loc[cells["status"] == "done", "cell_id"])
    return sorted(f"{c.method} N={c.n_robots} p={c.loss_p} seed={c.seed}" for c in grid.cells
                  if c.cell_id not in done)


def test_committed_ablation__is_complete() -> None:
    cells = RunStore(ROOT / "ablation").read_cells()
    assert missing_cells("ablation", cells) == []


@pytest.mark.parametrize("name", ["paper", *(["full"] if "full" in REPORTED else [])])
def test_committed_grid__is_complete_for_three_seeds(name: str) -> None:
    """Issues 13 and 33's done criterion: every cell of the paper grid, and of the full grid
    once its report is committed, done for >= 3 seeds (each done cell's rows in every mode
    are checked above)."""
    cells = RunStore(ROOT / name).read_cells()
    missing = missing_cells(name, cells)
    assert missing == [], f"reproduction/{name}: {len(missing)} cells not done, e.g. {missing[:3]}"


def test_committed_unfinished_cells__can_resume_from_a_committed_checkpoint(run) -> None:
    name, store, cells = run
    started = cells[(cells["status"] != "done") & (cells["train_episodes_done"] > 0)]
    for cid in started["cell_id"]:
        assert (store.root / "checkpoints" / f"{cid}.pt").is_file(), f"reproduction/{name}: {cid} has no checkpoint"


REBUILT_SUFFIXES = {".md", ".csv", ".tex", ".txt", ".json", ".html"}  # text: compared byte for byte


@pytest.mark.parametrize("name", [*REPORTED, *(n for n in GRID_FILE_REPORTS if (ROOT / n / "report").is_dir())])
def test_committed_report__is_what_the_current_code_rebuilds(name, tmp_path, monkeypatch) -> None:
    """``bench report --run reproduction/<name>`` on this checkout gives the committed
    report/: the same files, and every text file (claims page, tables, captions, index)
    byte for byte. Figures (PNG, PDF) must exist; their pixels are not compared, since
    font rasterization may differ between machines."""
    from reports.build import build_report

    committed = ROOT / name / "report"
    assert (committed / "claims.md").is_file(), f"reproduction/{name}/report/claims.md is not committed"
    monkeypatch.chdir(ROOT.parent)  # the index names the run relative to the repository
    against = GRID_FILE_REPORTS.get(name)
    out = build_report(Path("reproduction") / name, tmp_path / "report",
                       against=Path("reproduction") / against if against else None)
    files = {p.relative_to(committed) for p in committed.rglob("*") if p.is_file()}
    rebuilt = {p.relative_to(out) for p in out.rglob("*") if p.is_file()}
    assert files == rebuilt, f"reproduction/{name}/report: files differ from a rebuild"
    changed = [str(f) for f in sorted(files) if f.suffix in REBUILT_SUFFIXES
               and (committed / f).read_bytes() != (out / f).read_bytes()]
    assert not changed, (f"reproduction/{name}/report is stale: {changed} differ from `bench report` "
                         f"on this code; rebuild it with `bench report --run reproduction/{name}`")


def test_readme__claims_table_is_the_committed_reports() -> None:
    """docs/reproduction.md shows the committed report's claims table, success table and
    status table verbatim, and the README the verdict counts
    (``scripts/sync_readme_claims.py`` writes them), and once the full grid is reported its
    per-method leads, so no verdict, success rate or account of what is done can drift from
    the report."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("sync", ROOT.parent / "scripts" / "sync_readme_claims.py")
    sync = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(sync)  # type: ignore[union-attr]
    pages = sync.expected_blocks(ROOT / "paper")
    full = {"full_ordering"} if (ROOT / "full" / "report").is_dir() else set()
    assert set(pages[sync.PAGE]) == set(sync.BLOCKS) and set(pages[sync.README]) == {"verdicts", *full}
    for page, blocks in pages.items():
        text = (ROOT.parent / page).read_text(encoding="utf-8")
        for name, table in blocks.items():
            assert sync.readme_block(text, name) == table, \
                f"{page}'s {name} block differs from reproduction/paper/report; run scripts/sync_readme_claims.py"


def test_fig1a_five_seed_grid_file__adds_exactly_the_paper_grids_seeds_3_and_4() -> None:
    """reproduction/fig1a-5seeds.toml repeats PAPER_SETTINGS by hand; if they drift, its cells
    would get new ids and land beside, not inside, the paper grid's Fig. 1(a) cells."""
    from bench.design.grid_files import load_grid_file
    from paper.grids import paper

    extra = load_grid_file(ROOT / "fig1a-5seeds.toml").cells
    five, three = {c.cell_id for c in paper(5).cells}, {c.cell_id for c in paper(3).cells}
    assert {c.cell_id for c in extra} <= five - three
    assert {(c.method, c.n_robots, c.loss_p, c.seed) for c in extra} == {
        (m, n, 0.2, s) for m in ("hierarchical", "decentralized") for n in (20, 40, 60) for s in (3, 4)}


@pytest.mark.parametrize("name", [n for n in ("paper", "ablation", "full") if (ROOT / n / "manifest.json").is_file()])
def test_manifest__every_run_record_is_complete_or_says_why_not(name: str) -> None:
    """Each record holds its commit, machine, end, wall time and cells, or names the missing
    part in ``unrecorded`` with the reason (maintenance/complete_run_records.py); only the last
    record may be open, a run under way when its state was committed."""
    from bench.store.meta_schema import unexplained_parts

    runs = RunStore(ROOT / name).read_manifest()["runs"]
    gaps = {r["started"]: unexplained_parts(r) for r in runs[:-1]}
    gaps = {started: parts for started, parts in gaps.items() if parts}
    last = runs[-1]
    if last.get("ended") is not None or (last.get("unrecorded") or {}).get("ended"):
        if unexplained_parts(last):
            gaps[last["started"]] = unexplained_parts(last)
    assert not gaps, f"reproduction/{name}/manifest.json: records without these parts or a reason: {gaps}"
