"""Study figures from the trials frame (runtime ~4 s)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from envs.errors import BenchError
from studies.report import (
    _tick,
    build_study_report,
    importance_figure,
    is_paper_space,
    landscape_figure,
    landscape_table,
    slice_table,
)


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


def _other_space() -> pd.DataFrame:
    """A study of a baseline's parameters: two searched parameters, neither L nor |R_z|."""
    return pd.DataFrame({
        "study": ["b"] * 6, "number": range(6),
        "state": ["COMPLETE", "COMPLETE", "COMPLETE", "PRUNED", "FAIL", "COMPLETE"],
        "value": [0.5, 0.7, 0.9, 0.2, np.nan, 0.6],
        "success_rate": [0.5, 0.7, 0.9, np.nan, np.nan, 0.6], "team_return": [1.0] * 6,
        "ppo_lr": [1e-3, 1e-3, 5e-4, 5e-4, 1e-3, 2e-4], "hidden": [64, 128, 64, 64, 64, 128],
        "intermediate_json": ["{}"] * 6,
    })


def test_slice_landscape__means_complete_trials_per_value_and_counts_pruned_ones_by_hand() -> None:
    table = slice_table(_other_space())
    assert table[table["parameter"] == "ppo_lr"]["value"].tolist() == [2e-4, 5e-4, 1e-3]  # by value
    table = table.set_index(["parameter", "value"])
    assert list(table.index.get_level_values(0).unique()) == ["hidden", "ppo_lr"]
    assert table.loc[("ppo_lr", 1e-3), "mean"] == pytest.approx(0.6)  # (0.5 + 0.7) / 2: the failed trial counts nowhere
    assert table.loc[("ppo_lr", 5e-4), "mean"] == pytest.approx(0.9)  # the pruned trial's 0.2 is not averaged ...
    assert table.loc[("ppo_lr", 5e-4), "pruned"] == 1  # ... but counted
    assert table.loc[("hidden", 128), "complete"] == 2 and table.loc[("hidden", 64), "complete"] == 2
    assert table["complete"].sum() == 2 * 4 and table["pruned"].sum() == 2


def test_landscape_figure__a_study_of_other_parameters_gets_one_panel_per_parameter() -> None:
    built = landscape_figure(_other_space())
    visible = [ax for ax in built.fig.axes if ax.get_visible()]
    assert [ax.get_title() for ax in visible] == ["hidden", "ppo_lr"]
    assert any("1 pruned trial" in n for n in built.notes)
    # the paper's study (L x |R_z|) keeps its heatmap, with a C_max column too
    assert is_paper_space(_frame()) and is_paper_space(_frame().assign(c_max=500))
    assert not is_paper_space(_frame().assign(share_params=True))
    # a study with no finished trial yet says so, whichever its parameters
    unfinished = _other_space().assign(state="RUNNING")
    assert slice_table(unfinished).columns.tolist() == ["parameter", "value", "mean", "complete", "pruned"]
    assert landscape_figure(unfinished).notes == ["no finished trial"]


@pytest.mark.parametrize(("value", "label"), [(2e-4, "2e-4"), (0.003, "3e-3"), (0.01, "0.01"), (0.03, "0.03"),
                                              (0.0, "0.0"), (128, "128"), (False, "False")])
def test_slice_ticks_are_short(value: object, label: str) -> None:
    assert _tick(value) == label


def test_study_page__names_a_best_of_floats_and_booleans_as_they_are(tmp_path: Path) -> None:
    """The best configuration of a baseline's study prints ppo_lr=0.0005, not ppo_lr=0 (every
    value was once cast to int, as the paper's integer space allowed)."""
    frame = pd.concat([_other_space()] * 2, ignore_index=True).assign(number=range(12))
    frame["ppo_lr"], frame["hidden"], frame["action_path"], frame["state"] = 5e-4, 64, False, "COMPLETE"
    frame["value"] = 0.5
    frame.to_parquet(tmp_path / "trials.parquet")
    build_study_report(tmp_path)
    text = (tmp_path / "report" / "study.md").read_text()
    assert "action_path=False, hidden=64, ppo_lr=0.0005: mean objective" in text
