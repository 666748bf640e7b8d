"""scripts/compare_runs.py: train and eval rows of two runs compared bit for bit."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pandas as pd

_spec = importlib.util.spec_from_file_location(
    "compare_runs", Path(__file__).resolve().parents[2] / "scripts" / "compare_runs.py")
cmp = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(cmp)


def _run(root: Path, ret: float, wall: float, order=(0, 1)) -> Path:
    (root / "train").mkdir(parents=True)
    (root / "eval").mkdir()
    pd.DataFrame({"cell_id": ["c1"]}).to_parquet(root / "cells.parquet")
    train = pd.DataFrame({"cell_id": ["c1", "c1"], "episode": [0, 1], "team_return": [ret, 2.0],
                          "actor_loss": [np.nan, 0.5], "wall_s": [wall, wall]})
    train.iloc[list(order)].to_parquet(root / "train" / "c1-0.parquet")
    pd.DataFrame({"cell_id": ["c1"], "execution": ["argmax"], "episode": [0], "team_return": [ret],
                  "wall_s": [wall]}).to_parquet(root / "eval" / "c1.parquet")
    return root


def test_compare_runs__same_rows_other_order_and_wall_time_are_equal(tmp_path: Path, capsys) -> None:
    a = _run(tmp_path / "a", 1.0, wall=3.0)
    b = _run(tmp_path / "b", 1.0, wall=9.0, order=(1, 0))
    assert cmp.main([str(a), str(b), "--names", "host", "container"]) == 0
    out = capsys.readouterr().out
    assert "train: container == host for every row (2 rows, 1 cells)" in out
    assert "eval: container == host for every row (1 rows, 1 cells)" in out


def test_compare_runs__one_ulp_apart_is_a_difference(tmp_path: Path, capsys) -> None:
    a = _run(tmp_path / "a", 1.0, wall=3.0)
    b = _run(tmp_path / "b", float(np.nextafter(1.0, 2.0)), wall=3.0)
    assert cmp.main([str(a), str(b)]) == 1
    out = capsys.readouterr().out
    assert "train: right != left: column team_return differs at row 0 (cell_id=c1, episode=0)" in out
    assert "eval: right != left" in out


def test_compare_runs__missing_run_folder_is_exit_2_naming_it(tmp_path: Path, capsys) -> None:
    a = _run(tmp_path / "a", 1.0, wall=3.0)
    assert cmp.main([str(a), str(tmp_path / "nope")]) == 2
    assert f"{tmp_path / 'nope'} is not a run folder" in capsys.readouterr().err
