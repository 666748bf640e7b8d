"""Study figures from the trials frame (runtime ~4 s)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from envs.errors import BenchError
from studies.report import build_study_report, importance_figure, landscape_table


def _frame() -> pd.DataFrame:
    return pd.DataFrame({
        "study": ["t"] * 5, "number": range(5),
        "state": ["COMPLETE", "COMPLETE", "COMPLETE", "PRUNED", "FAIL"],
        "value": [0.5, 0.7, 0.9, 0.1, np.nan],
        "success_rate": [0.5, 0.7, 0.9, 0.1, np.nan], "team_return": [1.0, 2.0, 3.0, 0.0, np.nan],
        "ref_size": [4, 4, 8, 8, 2], "search_radius": [1, 1, 2, 1, 0],
    })


def test_landscape__means_complete_trials_per_cell_by_hand() -> None:
    mean, count = landscape_table(_frame())
    assert list(mean.index) == [0, 1, 2, 3] and list(mean.columns) == [2, 4, 8, 16, 32]
    assert mean.loc[1, 4] == pytest.approx(0.6)  # (0.5 + 0.7) / 2
    assert mean.loc[2, 8] == pytest.approx(0.9)
    assert np.isnan(mean.loc[1, 8])  # only a pruned trial there: not in the landscape
    assert count.loc[1, 4] == 2 and count.to_numpy().sum() == 3


def test_importance_figure__without_importances_says_why() -> None:
    built = importance_figure({"importances": {}, "reason": "too few trials: 1 complete"})
    assert built.notes == ["too few trials: 1 complete"]


def test_build_study_report__writes_png_pdf_and_summary(tmp_path: Path) -> None:
    _frame().to_parquet(tmp_path / "trials.parquet")
    (tmp_path / "importances.json").write_text(json.dumps(
        {"importances": {"ref_size": 0.8, "search_radius": 0.2}, "reason": None}))
    paths = build_study_report(tmp_path)
    names = sorted(p.name for p in paths)
    assert names == sorted(["study.md", *(f"study_{s}.{e}" for s in ("history", "landscape", "importances")
                                          for e in ("png", "pdf"))])
    assert all(p.stat().st_size > 0 for p in paths)
    text = (tmp_path / "report" / "study.md").read_text()
    assert "best: trial 2 ref_size=8, search_radius=2" in text


def test_build_study_report__without_trials_is_an_error(tmp_path: Path) -> None:
    with pytest.raises(BenchError, match="trials.parquet"):
        build_study_report(tmp_path)
