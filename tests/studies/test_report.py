"""Study figures from the trials frame (runtime ~4 s)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from envs.errors import BenchError
from studies.report import build_study_report, importance_figure, landscape_figure, landscape_table


def _frame() -> pd.DataFrame:
    return pd.DataFrame({
        "study": ["t"] * 5, "number": range(5),
        "state": ["COMPLETE", "COMPLETE", "COMPLETE", "PRUNED", "FAIL"],
        "value": [0.5, 0.7, 0.9, 0.1, np.nan],
        "success_rate": [0.5, 0.7, 0.9, 0.1, np.nan], "team_return": [1.0, 2.0, 3.0, 0.0, np.nan],
        "ref_size": [4, 4, 8, 8, 2], "search_radius": [1, 1, 2, 1, 0],
        "intermediate_json": ['{"1": 0.2, "2": 0.5}', '{"1": 0.4, "2": 0.7}', '{"1": 0.3, "2": 0.9}',
                              '{"1": 0.1}', "{}"],
    })


def test_landscape__means_complete_trials_and_counts_pruned_ones_by_hand() -> None:
    mean, n_comp, n_pruned = landscape_table(_frame())
    assert list(mean.index) == [0, 1, 2, 3] and list(mean.columns) == [2, 4, 8, 16, 32]
    assert mean.loc[1, 4] == pytest.approx(0.6)  # (0.5 + 0.7) / 2
    assert mean.loc[2, 8] == pytest.approx(0.9)
    assert np.isnan(mean.loc[1, 8])  # only a pruned trial there: no mean ...
    assert n_pruned.loc[1, 8] == 1 and n_comp.loc[1, 8] == 0  # ... but counted as pruned
    assert n_comp.loc[1, 4] == 2 and n_comp.to_numpy().sum() == 3 and n_pruned.to_numpy().sum() == 1
    assert n_comp.loc[0, 2] == 0 and n_pruned.loc[0, 2] == 0  # a failed trial counts nowhere


def test_landscape_figure__labels_pruned_configurations() -> None:
    built = landscape_figure(_frame())
    texts = [t.get_text() for t in built.fig.axes[0].texts]
    assert "pruned\n1 pr" in texts and "0.60\n2 ok" in texts
    assert any("every trial pruned" in n for n in built.notes)


def test_importance_figure__without_importances_says_why() -> None:
    built = importance_figure({"importances": {}, "reason": "too few trials: 1 complete"})
    assert built.notes == ["too few trials: 1 complete"]


def test_build_study_report__writes_figures_markdown_and_html(tmp_path: Path) -> None:
    _frame().to_parquet(tmp_path / "trials.parquet")
    (tmp_path / "importances.json").write_text(json.dumps(
        {"importances": {"ref_size": 0.8, "search_radius": 0.2}, "reason": None, "caveat": "rough"}))
    paths = build_study_report(tmp_path)
    names = sorted(p.name for p in paths)
    assert names == sorted(["study.md", "study.html",
                            *(f"study_{s}.{e}" for s in ("history", "landscape", "curves", "importances")
                              for e in ("png", "pdf"))])
    assert all(p.stat().st_size > 0 for p in paths)
    text = (tmp_path / "report" / "study.md").read_text()
    # replicates default to 2: only (4, 1) has two complete, unpruned ones; (8, 2) scores more once
    assert "ref_size=4, search_radius=1: mean objective 0.6000 over 2 replicates" in text
    # the objective is a success rate: the t interval on the logit scale, inside [0, 1] (a plain one: -0.67, 1.87)
    assert "| 4 | 1 | 2 | 0 | 0 | 0.6000 | [0.0070, 0.9970] |" in text
    # update 1 vs final over the 3 complete trials: ranks (1,3,2) vs (1,2,3), rho = 1 - 6*2/24
    assert "| 1 |  | 3 | 0.50 |" in text
    page = (tmp_path / "report" / "study.html").read_text()
    assert page.count("<table") == 3 and '<img src="study_curves.png"' in page
def test_build_study_report__without_trials_is_an_error(tmp_path: Path) -> None:
    with pytest.raises(BenchError, match="trials.parquet"):
        build_study_report(tmp_path)
