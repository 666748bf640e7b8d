"""The env perf suite builds its table; without the anchor venv it says so."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import bench.perf_env as perf


def test_env_suite_reports_our_throughput_per_layout_and_batch() -> None:
    df = perf.run_env_suite(
        ns=(20,), batches=(1, 3), steps=10, target_seconds=0.0, include_anchors=False,
        real_map=None,
    )
    assert list(df.columns) == perf.COLUMNS
    assert df[["mode", "batch"]].values.tolist() == [
        ["core", 1], ["core+obs", 1], ["core", 3], ["core+obs", 3],
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
    )
    assert df["sim"].tolist() == ["ours"]
    assert "run `make anchors`" in df["note"].iloc[0]
