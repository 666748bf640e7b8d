"""bench export: marl-eval's raw-data JSON (checked against its documented layout, and loaded
with marl-eval's own data-processing functions in .marl-eval-venv) and tidy CSV tables, on
the committed paper reproduction and a synthetic run."""
from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import pandas as pd
import pytest

from bench.cli import main
from bench.export.command import export_run
from bench.store.run_store import RunStore
from tests.bench.conftest import REPO, snapshot

PAPER = REPO / "reproduction" / "paper"
MARL_EVAL_PY = REPO / ".marl-eval-venv" / "bin" / "python"


@pytest.fixture(scope="module")
def paper_tables() -> tuple[pd.DataFrame, pd.DataFrame]:
    store = RunStore(PAPER)
    return store.read_cells(), store.read_eval()


@pytest.fixture(scope="module")
def paper_export(tmp_path_factory) -> tuple[dict, dict, Path]:
    out = tmp_path_factory.mktemp("export")
    full = export_run(PAPER, "marl-eval", out / "all.json")[0]
    balanced = export_run(PAPER, "marl-eval", out / "balanced.json", balanced=True)[0]
    return json.loads(full.read_text()), json.loads(balanced.read_text()), balanced


def _check_layout(data: dict) -> None:
    """marl-eval's README layout: environment -> task -> algorithm -> run -> step_k
    {step_count: int, metric: [values]} and absolute_metrics {metric: [values]}."""
    assert list(data) == ["warehouse_v0"]
    for algorithms in data["warehouse_v0"].values():
        for algorithm, runs in algorithms.items():
            assert "," not in algorithm
            for run, steps in runs.items():
                assert run.startswith("seed_") and set(steps) == {"step_0", "absolute_metrics"}
                step = steps["step_0"]
                assert isinstance(step["step_count"], int) and step["step_count"] >= 0
                metrics = {k: v for k, v in step.items() if k != "step_count"}
                assert set(metrics) == set(steps["absolute_metrics"]) and "return" in metrics
                for values in [*metrics.values(), *steps["absolute_metrics"].values()]:
                    assert isinstance(values, list) and values and all(math.isfinite(v) for v in values)


def test_export_marl_eval__paper_reproduction_follows_the_documented_layout_and_holds_the_eval_rows(
        paper_export, paper_tables) -> None:
    full, balanced, _ = paper_export
    cells, evals = paper_tables
    _check_layout(full)
    _check_layout(balanced)
    done = cells[cells["status"] == "done"]
    assert sum(len(r) for a in full["warehouse_v0"].values() for r in a.values()) == len(done)
    cell = done[(done["method"] == "hierarchical") & (done["n_robots"] == 40) & (done["loss_p"] == 0.2)
                & (done["seed"] == 1)].iloc[0]
    step = full["warehouse_v0"]["warehouse-10-20-10-2-1_n40_p0.2"]["hierarchical"]["seed_1"]["step_0"]
    rows = evals[(evals["cell_id"] == cell["cell_id"]) & (evals["execution"] == "argmax")].sort_values("episode")
    assert step["success_rate"] == list(rows["success_rate"]) and step["return"] == list(rows["team_return"])
    train = pd.read_parquet(PAPER / "train" / cell["cell_id"], columns=["steps"])
    assert step["step_count"] == int(train["steps"].sum())
    pibt = full["warehouse_v0"]["warehouse-10-20-10-2-1_n40_p0.2"]["pibt"]["seed_0"]["step_0"]
    assert pibt["step_count"] == 0 and len(pibt["return"]) == int(cell["eval_episodes"])
    # balanced: every task has every algorithm with the same runs (marl-eval's matrices need it)
    tasks = balanced["warehouse_v0"]
    algs = {a for t in tasks.values() for a in t}
    assert algs == {"hierarchical", "decentralized", "ic3net", "pibt"}
    runs = {tuple(r) for t in tasks.values() for r in t.values()}
    assert runs == {("seed_0", "seed_1", "seed_2")} and all(set(t) == algs for t in tasks.values())


@pytest.mark.skipif(not MARL_EVAL_PY.exists(), reason="no .marl-eval-venv (run `make marl-eval`)")
def test_export_marl_eval__loads_with_marl_evals_data_processing_functions(paper_export) -> None:
    _, _, path = paper_export
    script = f"""
import json
from marl_eval.utils.data_processing_utils import create_matrices_for_rliable, data_process_pipeline
from marl_eval.utils.diagnose_data_errors import DiagnoseData
raw = json.load(open({str(path)!r}))
checks = DiagnoseData(raw).check_data()
processed = data_process_pipeline(raw_data=raw, metrics_to_normalize=["return"])
assert "extra" in processed, "data_process_pipeline refused the file"
scores, curves = create_matrices_for_rliable(processed, "warehouse_v0", ["return"])
print(json.dumps({{"checks": checks, "extra": processed["extra"]["number_of_runs"],
                  "shape": {{m: {{a: list(v.shape) for a, v in d.items()}} for m, d in scores.items()}}}}, default=str))
"""
    done = subprocess.run([str(MARL_EVAL_PY), "-c", script], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr + done.stdout
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert all(all(v for v in c.values()) for c in result["checks"].values()), result["checks"]
    assert result["extra"] == 3
    shape = result["shape"]["mean_norm_return"]
    assert set(shape) == {"hierarchical", "decentralized", "ic3net", "pibt"}
    assert all(s[0] == 3 and s[1] == 2 for s in shape.values())  # 3 seeds x the 2 tasks all four ran


@pytest.fixture
def toy_run(toy: str, tmp_path: Path) -> Path:
    from bench.design.cells import Cell
    from bench.design.grids import Grid
    from tests.bench.conftest import toy_spec, write_finished_store

    grid = Grid("toygrid", "test", tuple(Cell.make(**toy_spec(seed=s)) for s in (0, 1)))
    write_finished_store(tmp_path / "run", grid)
    return tmp_path / "run"


def test_export_csv__tidy_tables_hold_every_row_once_with_its_config(toy_run: Path) -> None:
    written = export_run(toy_run, "csv")
    assert [p.name for p in written] == ["cells.csv", "train.csv", "eval.csv"]
    assert all(p.parent == toy_run / "export" / "csv" for p in written)
    store = RunStore(toy_run)
    cells = store.read_cells().set_index("cell_id")
    train = pd.read_csv(written[1])
    evals = pd.read_csv(written[2])
    stored = store.read_train()
    assert len(train) == len(stored) and not train.duplicated(["cell_id", "episode"]).any()
    merged = train.merge(stored, on=["cell_id", "episode"], suffixes=("", "_s"))
    assert (merged["team_return"] == merged["team_return_s"]).all()  # full precision
    assert (train["seed"] == train["cell_id"].map(cells["seed"])).all()
    assert {"method", "n_robots", "loss_p", "layout"} <= set(train.columns)
    assert len(evals) == len(store.read_eval()) and set(evals["execution"]) == {"argmax", "sample", "sample@0.5"}


def test_export_cli__existing_out_refused_without_yes_and_bad_mode_is_one_line(
        toy_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / "mine.json"
    target.write_text("my notes")
    before = snapshot(toy_run)
    for argv, needle in (
        (["export", "--run", str(toy_run), "--format", "marl-eval", "--out", str(target)], "pass --yes"),
        (["export", "--run", str(toy_run), "--format", "marl-eval", "--execution", "greedy"], "--execution 'greedy'"),
        (["export", "--run", str(toy_run), "--format", "xml"], "--format"),
        (["export", "--run", str(tmp_path / "nope"), "--format", "csv"], "nope"),
    ):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        err = capsys.readouterr().err.strip()
        assert exc.value.code == 2 and len(err.splitlines()) == 1 and needle in err, err
    assert target.read_text() == "my notes" and snapshot(toy_run) == before
    for fmt, default in (("marl-eval", toy_run / "export" / "marl-eval.json"),
                         ("csv", toy_run / "export" / "csv" / "cells.csv")):
        with pytest.raises(SystemExit) as exc:
            main(["export", "--run", str(toy_run), "--format", fmt])  # the first export: written
        assert exc.value.code == 0
        first = default.read_bytes()
        default.write_bytes(b"edited")
        with pytest.raises(SystemExit) as exc:  # the default target is never replaced silently either
            main(["export", "--run", str(toy_run), "--format", fmt])
        err = capsys.readouterr().err.strip()
        assert exc.value.code == 2 and len(err.splitlines()) == 1 and "pass --yes" in err, err
        assert default.read_bytes() == b"edited"
        with pytest.raises(SystemExit) as exc:
            main(["export", "--run", str(toy_run), "--format", fmt, "--yes"])
        assert exc.value.code == 0 and default.read_bytes() == first
    with pytest.raises(SystemExit) as exc:
        main(["export", "--run", str(toy_run), "--format", "marl-eval", "--out", str(target), "--yes"])
    assert exc.value.code == 0
    _check_layout(json.loads(target.read_text()))
