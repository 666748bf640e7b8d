"""Each learned method's ``preset = "tuned"`` is its committed study's winner (issue 47,
decision 0215): a published preset's values equal what studies/published.py computes from
the study's committed files, and a preset still unpublished names a study that has not
finished. A re-run study that changes its winner fails here until the preset follows."""
from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from algorithms.registry import method_class
from bench.design.cells import Cell
from envs.errors import BenchError
from studies.definitions import DEFINITIONS
from studies.published import published_values

LEARNED = ("decentralized", "ic3net", "hierarchical")
REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("method", LEARNED)
def test_tuned_preset_is_its_committed_studys_winner(method: str) -> None:
    preset = method_class(method).presets["tuned"]
    definition = REPO / preset.source
    assert definition == DEFINITIONS / f"{method}.toml", "the preset names its method's definition"
    if preset.pending:
        with pytest.raises(BenchError, match="trials finished|run bench tune"):
            published_values(definition)  # a finished study's winner must be published
        return
    assert dict(preset.values) == published_values(definition)
    cell = Cell.make(method=method, n_robots=40, loss_p=0.4, preset="tuned")
    assert cell.method_params().protocol == "mappo"  # type: ignore[attr-defined]


def _write_study(folder: Path, states: list[str], replicates: int = 2) -> None:
    """A minimal committed study of the decentralized definition: one row per trial, the
    odd trials (ppo_lr 5e-4) scoring 0.51 and the even ones (ppo_lr 1e-3) 0.50; pruned trials
    at hidden 32, a configuration of their own."""
    folder.mkdir(parents=True)
    rows = [{"number": i, "state": s, "value": 0.5 + 0.01 * (i % 2), "success_rate": 0.5, "team_return": 1.0,
             "ppo_lr": [0.001, 0.0005][i % 2], "entropy_coef": 0.01, "hidden": 32 if s == "PRUNED" else 64,
             "critic_hidden": 128,
             "patch_radius": 2, "action_path": False} for i, s in enumerate(states)]
    pd.DataFrame(rows).to_parquet(folder / "trials.parquet", index=False)
    (folder / "study.json").write_text(json.dumps({"replicates": replicates}))


def test_published_values_are_the_params_and_the_best_mean_configuration(tmp_path: Path) -> None:
    _write_study(tmp_path / "tuned-decentralized", ["COMPLETE"] * 72)
    values = published_values(DEFINITIONS / "decentralized.toml", root=tmp_path)
    assert values == {"protocol": "mappo", "ppo_lr": 0.0005, "entropy_coef": 0.01, "hidden": 64,
                      "critic_hidden": 128, "patch_radius": 2, "action_path": False}


def test_published_values_count_the_studys_own_replicates(tmp_path: Path) -> None:
    """With 3 replicates per configuration, a configuration with 2 complete trials is not
    eligible: the better-scoring ppo_lr 5e-4 (2 trials) loses to 1e-3 (3 trials)."""
    _write_study(tmp_path / "tuned-decentralized", ["COMPLETE"] * 5 + ["PRUNED"] * 67, replicates=3)
    assert published_values(DEFINITIONS / "decentralized.toml", root=tmp_path)["ppo_lr"] == 0.001
    (tmp_path / "tuned-decentralized" / "study.json").write_text("{}")  # a study from before replicates were stored: 2
    assert published_values(DEFINITIONS / "decentralized.toml", root=tmp_path)["ppo_lr"] == 0.0005


def test_a_definition_without_fixed_params_gives_only_the_searched_values(tmp_path: Path) -> None:
    text = (DEFINITIONS / "decentralized.toml").read_text()
    text = text.replace('[params]  #', '# [params] #').replace('protocol = "mappo"', "")
    text = text.replace('protocol = "protocol.toml"', f'protocol = "{DEFINITIONS / "protocol.toml"}"')
    (tmp_path / "bare.toml").write_text(text)
    _write_study(tmp_path / "tuned-decentralized", ["COMPLETE"] * 72)
    assert "protocol" not in published_values(tmp_path / "bare.toml", root=tmp_path)


def test_an_unfinished_or_missing_study_gives_no_preset(tmp_path: Path) -> None:
    folder = tmp_path / "tuned-decentralized"
    with pytest.raises(BenchError, match=f"'tuned-decentralized' \\('{folder}'\\): no trials.parquet and study.json"):
        published_values(DEFINITIONS / "decentralized.toml", root=tmp_path)
    _write_study(folder, ["COMPLETE"] * 40 + ["PRUNED"] * 31 + ["RUNNING"])
    with pytest.raises(BenchError, match="71 of 72 trials finished; a preset takes the winner of a finished study"):
        published_values(DEFINITIONS / "decentralized.toml", root=tmp_path)
    (folder / "study.json").unlink()  # one of the two files missing is as bad as both
    with pytest.raises(BenchError, match="no trials.parquet and study.json"):
        published_values(DEFINITIONS / "decentralized.toml", root=tmp_path)
