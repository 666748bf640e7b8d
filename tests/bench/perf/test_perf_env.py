"""The env perf suite builds its table; without the anchor venv it says so."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import bench.perf.env as perf


def test_env_suite_reports_our_throughput_per_layout_and_batch() -> None:
    df = perf.run_env_suite(
        ns=(20,), batches=(1, 3), steps=10, target_seconds=0.0, include_anchors=False,
        real_map=None,
    )
    assert list(df.columns) == perf.COLUMNS
    assert df[["mode", "batch"]].values.tolist() == [
        ["core", 1], ["core+obs", 1], ["core", 3], ["core+obs", 3], ["pettingzoo", 1],
    ]
    assert (df["layout"] == "wh20").all() and (df["n_robots"] == 20).all()
    assert (df["steps"] == 10).all()
    assert np.allclose(df["agent_steps_per_s"], df["env_steps_per_s"] * 20)
    assert df["vs_pogema"].isna().all()
    assert "|---|" in perf.to_markdown(df)


def test_missing_anchor_venv_is_a_note_not_a_failure(monkeypatch: pytest.MonkeyPatch,
                                                     tmp_path: Path) -> None:
    monkeypatch.setattr(perf, "ANCHORS_PY", tmp_path / ".anchors-venv" / "bin" / "python")
    df = perf.run_env_suite(
        ns=(20,), batches=(1,), steps=5, target_seconds=0.0, real_map=None, with_obs=False,
        with_pettingzoo=False,
    )
    assert df["sim"].tolist() == ["ours"]
    assert "run `make anchors`" in df["note"].iloc[0]


def test_pettingzoo_row_is_compared_with_pogemas_pettingzoo_wrapper(
        monkeypatch: pytest.MonkeyPatch) -> None:
    def fake_anchors(cases, steps, target_seconds):
        return [
            dict(sim="pogema", mode="env", layout="wh20", n_robots=20, batch=1,
                 agent_steps_per_s=1000.0, note="collision_system=soft"),
            dict(sim="pogema", mode="pettingzoo", layout="wh20", n_robots=20, batch=1,
                 agent_steps_per_s=10.0, note="collision_system=soft"),
        ], ""
    monkeypatch.setattr(perf, "run_anchors", fake_anchors)
    df = perf.run_env_suite(ns=(20,), batches=(1,), steps=5, target_seconds=0.0,
                            real_map=None, with_obs=False)
    ours = df[df["sim"] == "ours"].set_index("mode")
    assert ours.loc["core", "vs_pogema"] == pytest.approx(ours.loc["core", "agent_steps_per_s"] / 1000)
    assert ours.loc["pettingzoo", "vs_pogema"] == pytest.approx(
        ours.loc["pettingzoo", "agent_steps_per_s"] / 10)


def test_pettingzoo_row_times_whole_steps_of_our_adapter() -> None:
    steps, secs = perf.time_pettingzoo(perf.load_layout("wh20"), 20, steps=7, target_seconds=0.0)
    assert steps == 7 and secs > 0


@pytest.mark.skipif(not perf.ANCHORS_PY.exists(), reason="no .anchors-venv (run `make anchors`)")
def test_anchors_measure_pogema_soft_through_env_and_pettingzoo() -> None:
    df = perf.run_env_suite(ns=(20,), batches=(1,), steps=10, target_seconds=0.0,
                            real_map=None, with_obs=False)
    pogema = df[df["sim"] == "pogema"]
    assert sorted(pogema["mode"]) == ["env", "pettingzoo"]
    assert pogema["note"].str.contains("collision_system=soft").all()
    assert df[df["sim"] == "ours"]["vs_pogema"].notna().all()
