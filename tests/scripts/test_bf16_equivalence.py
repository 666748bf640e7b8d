"""scripts/bf16_equivalence.py: decision 0240's check (its TOST, its seeds, its bookkeeping),
run end to end on a tiny configuration."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from bench.design.grids import get_grid, grid_builders

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("bf16_equivalence", ROOT / "scripts" / "bf16_equivalence.py")
eq = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(eq)

TINY = ["--power-sims", "20", "--methods", "decentralized", "--seeds", "2", "--set", "n_robots=4", "layout=tiny",
        "episodes=4", "horizon=10", "eval_episodes=4", "groups=2"]


def test_the_constants_are_decision_0240s() -> None:
    text = (ROOT / "docs/decisions/0240-the-bf16-equivalence-check-decided-in-advance.md").read_text()
    assert (eq.DELTA, eq.ALPHA, len(eq.SEEDS), eq.SEEDS[0], eq.SEEDS[-1]) == (0.05, 0.05, 20, 1000, 1019)
    assert "delta = 0.05" in text and "alpha = 0.05" in text and "seeds 1000-1019" in text
    assert eq.PROBE["n_robots"] == 20 and eq.PROBE["loss_p"] == 0.2 and eq.PROBE["episodes"] == 2000
    assert eq.PROTOCOL == "paper" and eq.METHODS == ("hierarchical", "decentralized", "ic3net")


@pytest.mark.slow  # builds every named grid (a minute on a loaded box)
def test_the_check_s_seeds_are_no_published_cell_s() -> None:
    published: set[int] = set()
    for name in grid_builders():
        published |= {c.seed for c in get_grid(name).cells}
    for path in ROOT.glob("reproduction/*/cells.parquet"):
        published |= set(pd.read_parquet(path, columns=["seed"])["seed"].astype(int))
    assert published and not published & set(eq.SEEDS)


def test_tost__is_the_two_one_sided_scipy_tests_and_agrees_with_the_90_percent_interval() -> None:
    rng = np.random.default_rng(7)
    for _ in range(200):
        d = rng.normal(rng.uniform(-0.08, 0.08), rng.uniform(0.005, 0.1), 20)
        t = eq.tost(d)
        p_low = stats.ttest_1samp(d, -0.05, alternative="greater").pvalue
        p_high = stats.ttest_1samp(d, 0.05, alternative="less").pvalue
        assert (t["p_low"], t["p_high"]) == pytest.approx((p_low, p_high))
        inside = -0.05 < t["ci90"][0] and t["ci90"][1] < 0.05  # TOST at alpha = CI at 1 - 2 alpha
        assert t["equivalent"] == (max(p_low, p_high) < 0.05) == inside


def test_tost__decides_the_clear_cases() -> None:
    rng = np.random.default_rng(1)
    assert eq.tost(rng.normal(0.0, 0.02, 20))["equivalent"]
    assert not eq.tost(rng.normal(0.08, 0.02, 20))["equivalent"]  # a real difference
    assert not eq.tost(rng.normal(0.0, 0.3, 20))["equivalent"]  # too noisy to tell: undecided, not allowed
    assert eq.tost(np.zeros(5))["equivalent"] and not eq.tost(np.full(5, 0.06))["equivalent"]
    assert not eq.tost(np.array([0.0]))["equivalent"]


def test_verdict__a_missing_cell_makes_the_check_incomplete() -> None:
    rows = pd.DataFrame([{"method": "ic3net", "seed": s, "precision": a, "success_sample": 0.5,
                          "success_argmax": 0.5, "train_cpu_s": 1.0} for s in (1000, 1001) for a in ("fp32", "bf16")])
    done = eq.verdict(rows, ("ic3net",), (1000, 1001))["ic3net"]
    assert done["complete"] and done["decision"].startswith("equivalent")
    part = eq.verdict(rows.iloc[:-1], ("ic3net",), (1000, 1001))["ic3net"]
    assert not part["complete"] and part["decision"] == "incomplete" and part["pairs"] == 1


@pytest.mark.slow  # trains 4 tiny cells end to end
def test_script__trains_both_arms_writes_rows_and_verdict_and_resumes(tmp_path: Path, capsys) -> None:
    out = tmp_path / "eq"
    assert eq.main([*TINY, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert text.startswith("NOT decision 0240 (a test configuration): 4 cells")
    assert "cost:" in text.splitlines()[1] and "worker-hours" in text and "planned power" in text
    rows = pd.read_csv(out / "rows.csv")
    assert sorted(zip(rows["seed"], rows["precision"], strict=True)) == [
        (1000, "bf16"), (1000, "fp32"), (1001, "bf16"), (1001, "fp32")]
    verdict = json.loads((out / "verdict.json").read_text())
    assert verdict["check"] == "test configuration" and verdict["methods"]["decentralized"]["complete"]
    assert "decentralized: " in text.splitlines()[-1]
    stamps = {p.name: p.stat().st_mtime_ns for p in (out / "cells").iterdir()}
    assert eq.main([*TINY, "--out", str(out)]) == 0  # nothing trains again
    assert {p.name: p.stat().st_mtime_ns for p in (out / "cells").iterdir()} == stamps
    assert "seed 1000" not in capsys.readouterr().out


def test_run_cell__resumes_from_its_checkpoint_as_the_uninterrupted_cell(tmp_path: Path) -> None:
    import torch

    from bench.execute.plan import cell_spec
    from bench.execute.worker import CellWorker

    cell = eq.probe_cells(("decentralized",), (1000,), {**eq.PROBE, "n_robots": 4, "layout": "tiny", "episodes": 6,
                                                        "horizon": 10, "eval_episodes": 4, "groups": 2}, "paper")[1]
    assert eq.arm_of(cell) == "bf16"
    whole = eq.run_cell(cell, tmp_path / "a", 100)
    part = CellWorker().train_chunk(cell_spec(cell), [], 0, 1)  # one update, then "killed"
    ckpt = tmp_path / "b" / "checkpoints" / f"{cell.cell_id}.pt"
    ckpt.parent.mkdir(parents=True)
    torch.save({"method": part["state"], "iterations": part["iterations"], "cpu_s": 0.0}, ckpt)
    resumed = eq.run_cell(cell, tmp_path / "b", 100)
    assert not ckpt.exists()
    assert (resumed["success_sample"], resumed["success_argmax"]) == (whole["success_sample"], whole["success_argmax"])


@pytest.mark.parametrize(("args", "what"), [(["--dry-run", "--shard", "2/2"], "--shard '2/2'"),
                                            (["--dry-run", "--seeds", "40"], "--seeds 40"),
                                            (["--dry-run", "--set", "budget=3"], "--set 'budget=3'"),
                                            ([], "--out")])
def test_bad_input__one_line_and_status_2(args: list[str], what: str, capsys) -> None:
    assert eq.main(args) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith(f"bf16_equivalence: {what}")
