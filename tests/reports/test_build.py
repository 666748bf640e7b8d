"""build_report on synthetic stores written with the bench's own writer: every file, a
store with failed/pending/missing cells, a smoke-sized store, and user errors.
Runtime: about 10 s (each build renders three figures to PNG and PDF)."""
from __future__ import annotations

import html
import re

import pandas as pd
import pytest
from PIL import Image

from envs.errors import BenchError
from reports.build import build_report
from reports.tables.leaders import PER_METHOD_HEADING
from tests.reports.synthetic import frames, smoke_specs, write_store

EXPECTED = [
    "fig1_training.png", "fig1_training.pdf", "fig2_success_percentiles.png",
    "fig2_success_percentiles.pdf", "fig3_comm_payload.png", "fig3_comm_payload.pdf",
    "table1_safety.md", "table1_safety.tex", "table1_safety.csv", "summary.md", "summary.csv",
    "claims.md", "index.html", "index.md",
]


@pytest.fixture(scope="module")
def paper_run(tmp_path_factory):
    run = tmp_path_factory.mktemp("paper_run")
    write_store(run, *frames(seeds=2, episodes=60, eval_eps=10))
    return run, build_report(run)


def test_build_report__writes_every_file_into_run_report(paper_run):
    run, out = paper_run
    assert out == run / "report"
    for name in EXPECTED:
        assert (out / name).stat().st_size > 0, name
    assert not list(out.glob(".*.tmp"))  # atomic writes leave no temporaries
    assert (out / "index.html").stat().st_mode & 0o777 == 0o644  # readable when served
    for name in EXPECTED[:6:2]:
        w, h = Image.open(out / name).size
        assert w == 700 and 300 < h < 900  # 3.5 in at 200 dpi
    assert (out / "fig1_training.pdf").read_bytes().startswith(b"%PDF")


def test_build_report__tables_hold_the_paper_layout_and_values(paper_run):
    _, out = paper_run
    t1 = pd.read_csv(out / "table1_safety.csv")
    assert list(t1["n_robots"]) == [20, 40, 60, 80, 90, 100]  # the paper's five + N = 20 of the run
    assert t1["paper_correction_rate"].isna().tolist() == [True] + [False] * 5
    assert set(t1["status"]) == {"ok"} and (t1["seeds"] == 2).all()
    assert t1.loc[t1["n_robots"] == 60, "paper_mean_candidates"].item() == 16.44
    assert (t1["collision_rate"] == 0).all() and t1["correction_rate"].between(0.03, 0.036).all()
    md = (out / "table1_safety.md").read_text()
    assert "| 90 | 0.00% [0.00, 0.00] | 0.00% |" in md and "6.54%" in md
    assert "\\begin{tabular}" in (out / "table1_safety.tex").read_text()
    s = pd.read_csv(out / "summary.csv")
    assert len(s) == 18 + 3 + 6 and (s["seeds"] == 2).all() and (s["ci_over"] == "seeds").all()
    hier20 = s[(s["method"] == "hierarchical") & (s["n_robots"] == 20) & (s["loss_p"] == 0.2)]
    assert hier20["payload_scalars_per_step"].item() == 20 * 3 * 3


def test_build_report__index_links_everything_with_the_manifest(paper_run):
    _, out = paper_run
    md, html = (out / "index.md").read_text(), (out / "index.html").read_text()
    for name in EXPECTED[:-2]:
        assert f"({name})" in md and f"href='{name}'" in html, name
    assert "deadbeef" in md and "deadbeef" in html  # git sha of the manifest
    assert "bench run --grid synthetic" in html
    assert "Every cell of the store is done." in md
    assert md.count("**not enough seeds**") == 10  # 2 seeds per configuration: every statistical claim
    assert "**supported**" not in md


def test_build_report__index_page_shows_each_learned_methods_leads_as_in_leaders_md(paper_run):
    """Issue 33: how each learned method compares, on the page a user opens first, cell for
    cell as in leaders.md's "Per method" table."""
    _, out = paper_run
    page, leaders = (out / "index.html").read_text(), (out / "leaders.md").read_text()
    rows = [ln for ln in leaders.split(PER_METHOD_HEADING, 1)[1].split("\n## ", 1)[0].splitlines()
            if ln.startswith("| argmax |")]
    assert len(rows) == 3  # the synthetic run's three learned methods, argmax only
    table = page[page.index("<caption>Per learned method and mode"):]
    table = table[:table.index("</table>")]
    shown = [html.unescape(c) for c in re.findall(r"<td[^>]*>(.*?)</td>", table)]
    assert shown == [c.strip() for row in rows for c in row.strip().strip("|").split("|")]
    assert page.index("Per learned method and mode") < page.index("Who leads where")


def test_build_report__two_seeds_never_print_supported(paper_run):
    run, out = paper_run
    for at in ("paper", "run"):
        build_report(run, claims_at=at)
        claims = pd.read_csv(out / "claims.csv")
        assert "supported" not in set(claims["verdict"]), at
        assert "**supported**" not in (out / "index.md").read_text()
        assert "| supported |" not in (out / "claims.md").read_text()
    assert set(claims["scope"]) == {"paper", "run"}
    build_report(run)


def test_build_report__calibration_is_the_runs_own_or_none(tmp_path):
    """No calibration is copied from another run; a run's own table is linked as its own, a
    table whose meta names another run is labelled so."""
    import json

    from paper.sections import CALIBRATION

    run = tmp_path / "run"
    write_store(run, *frames(seeds=2, episodes=30, eval_eps=6))
    out = build_report(run)
    claims = (out / "claims.md").read_text()
    assert not (out / "calibration.json").exists() and "has no calibration of its own yet" in claims
    rep = json.loads(CALIBRATION.read_text())
    rep["meta"]["run"] = str(run)
    (out / "calibration.json").write_text(json.dumps(rep))
    claims = (build_report(run) / "claims.md").read_text()
    assert "[calibration](calibration.md) (this run's own, at its seed counts)" in claims
    cal = (out / "calibration.md").read_text()
    assert "| no_collisions | 300 episodes | null | binomial |" in cal and "**NO**" not in cal
    assert "## Coverage of the 95% intervals" in cal
    rep["meta"]["run"] = "reproduction/paper"
    (out / "calibration.json").write_text(json.dumps(rep))
    assert "**not this run's own**" in (build_report(run) / "claims.md").read_text()


def test_build_report__is_deterministic(paper_run):
    run, out = paper_run
    before = {n: (out / n).read_text() for n in ("summary.csv", "claims.md", "table1_safety.csv")}
    build_report(run)
    assert {n: (out / n).read_text() for n in before} == before


def test_build_report__missing_and_failed_cells_still_build_and_are_listed(tmp_path):
    cells, train, evals = frames(seeds=1, episodes=30, eval_eps=6)
    fail = (cells["method"] == "hierarchical") & (cells["n_robots"] == 80) & (cells["loss_p"] == 0.2)
    cells.loc[fail, ["status", "error"]] = ["failed", "Traceback ...\nMemoryError: out of memory"]
    pend = (cells["method"] == "ic3net") & (cells["n_robots"] == 60)
    cells.loc[pend, "status"] = "pending"
    drop = cells["method"] == "decentralized"  # never in the store at all
    train = train[~train["cell_id"].isin(cells.loc[fail | pend | drop, "cell_id"])]
    evals = evals[~evals["cell_id"].isin(cells.loc[fail | pend | drop, "cell_id"])]
    write_store(tmp_path, cells[~drop], train, evals)
    out = build_report(tmp_path)
    for name in EXPECTED:
        assert (out / name).exists(), name
    md = (out / "index.md").read_text()
    assert "1 failed" in md and "3 pending" in md
    assert "MemoryError: out of memory" in md
    assert "the run has no training data" not in md  # hierarchical N=20..60 are there
    assert "N = 20: no decentralized training data" in md
    t1 = (out / "table1_safety.md").read_text()
    assert "| 80 | not run |" in t1 and "lacks: 80" in t1
    claims = (out / "claims.md").read_text()
    assert ("| [hier_above_dec](#hier_above_dec) | Hierarchical above decentralized (final training "
            "reward) | **not enough seeds** | training (sampled): not enough seeds |") in claims
    assert "| paper | N = 80, p = 0.2 | training (sampled) | not enough seeds | 0 seeds" in claims


def test_build_report__smoke_sized_store_plots_what_it_has(tmp_path):
    write_store(tmp_path, *frames(episodes=8, eval_eps=4, specs=smoke_specs()))
    (tmp_path / "replays").mkdir()
    (tmp_path / "replays" / "abc-ep0.gif").write_bytes(b"GIF89a")  # as `bench replay` writes
    out = build_report(tmp_path)
    md = (out / "index.md").read_text()
    assert "[replays/abc-ep0.gif](replays/abc-ep0.gif)" in md  # copied: the folder is self-contained
    assert (out / "replays" / "abc-ep0.gif").read_bytes() == b"GIF89a"
    assert "(a) the run has no training data for N = 20, 40, 60 at p = 0.2" in md
    assert "the run has no hierarchical or IC3Net evaluation for N = 40, 60" in md
    claims = (out / "claims.md").read_text()
    assert ("| [payload_ratio](#payload_ratio) | Payload ratio equals (Z-1)/(N-1) | "
            "**verified by construction** |") in claims
    assert claims.count("**not enough seeds**") >= 5
    s = pd.read_csv(out / "summary.csv")
    assert set(s["method"]) == {"hierarchical", "decentralized", "ic3net", "pibt"}
    assert (s["ci_over"] == "episodes").all()


def test_build_report__every_cell_failed_still_builds_with_placeholders(tmp_path):
    cells, train, evals = frames(episodes=8, eval_eps=4, specs=smoke_specs())
    cells[["status", "error"]] = ["failed", "RuntimeError: boom"]
    write_store(tmp_path, cells, train.iloc[0:0], evals.iloc[0:0])
    out = build_report(tmp_path)
    for name in EXPECTED:
        assert (out / name).exists(), name
    md = (out / "index.md").read_text()
    assert "8 cells: 8 failed" in md and md.count("RuntimeError: boom") == 8
    assert "train/ holds no Parquet file" in md
    assert "nothing to plot" in md  # Fig. 3 note


def test_build_report__corrupt_file_is_skipped_and_reported(tmp_path):
    cells, train, evals = frames(episodes=8, eval_eps=4, specs=smoke_specs())
    write_store(tmp_path, cells, train, evals)
    victim = sorted((tmp_path / "eval").glob("*.parquet"))[0]
    victim.write_bytes(b"not parquet")
    md = (build_report(tmp_path) / "index.md").read_text()
    assert f"skipped eval/{victim.name}" in md
    # the cell counts as not done until `bench run --repair` recomputes it
    assert f"damaged file eval/{victim.name}: unreadable" in md and "--repair" in md


def test_build_report__not_a_run_directory_is_a_user_error(tmp_path):
    with pytest.raises(BenchError, match="cells.parquet not found"):
        build_report(tmp_path / "nowhere")


def test_build_report__links_studies_exported_beside_the_run(tmp_path):
    import optuna

    from studies.export import write_trials
    from studies.report import build_study_report

    run = tmp_path / "smoke"
    write_store(run, *frames(episodes=8, eval_eps=4, specs=smoke_specs()))
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(study_name="demo", direction="maximize")
    for ref, radius, value in ((2, 0, 0.1), (8, 2, 0.4), (4, 1, 0.3)):
        study.enqueue_trial({"ref_size": ref, "search_radius": radius})
        trial = study.ask({"ref_size": optuna.distributions.CategoricalDistribution([2, 4, 8]),
                           "search_radius": optuna.distributions.CategoricalDistribution([0, 1, 2])})
        study.tell(trial, value)
    write_trials(study, tmp_path / "studies" / "other")  # launched for no run: never linked
    out = build_report(run)
    index = (out / "index.md").read_text()
    assert "Study other" not in index and "No study records this run" in index
    assert "\"run\": \"smoke\"" in index  # says how to link one
    write_trials(study, tmp_path / "studies" / "demo", {"run": "smoke"})
    index = (build_report(run) / "index.md").read_text()  # linked, but `bench tune` built no report yet
    assert "Study demo" not in index and "study studies/demo was left out: it has no built report" in index
    built = build_study_report(tmp_path / "studies" / "demo")  # what `bench tune` does at its end
    out = build_report(run)
    index, page = (out / "index.md").read_text(), (out / "index.html").read_text()
    assert "Study demo" in index and "Study other" not in index
    for f in built:  # copied in, byte for byte (not rebuilt)
        assert (out / "studies" / "demo" / f.name).read_bytes() == f.read_bytes()
    assert "href='studies/demo/study.html'" in page and "../" not in page
