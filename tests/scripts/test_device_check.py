"""scripts/device_check.py: one line and status 2 without the device; at tiny sizes it times
every learned method on the device (simulated, tests/algorithms/fake_device.py) and on the
CPU and prints their env-steps/s and ratio."""
from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest
import torch

from tests.algorithms.fake_device import fake_cuda

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("device_check", ROOT / "scripts" / "device_check.py")
device_check = importlib.util.module_from_spec(_spec)
sys.modules["device_check"] = device_check
_spec.loader.exec_module(device_check)  # type: ignore[union-attr]

TINY = ["--n-robots", "6", "--layout", "tiny", "--groups", "3", "--horizon", "10", "--batch-episodes", "2",
        "--iterations", "1", "--warmup", "0"]


def test_without_cuda_one_line_and_status_2(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
                                            ) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert device_check.main(TINY) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no CUDA device is available" in err


def test_on_a_device_every_method_is_timed_against_the_cpu(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(torch.cuda, "synchronize", lambda device=None: None)
    monkeypatch.setattr(torch.cuda, "get_device_name", lambda device=None: "simulated")
    out = tmp_path / "dc.json"
    with fake_cuda():
        assert device_check.main([*TINY, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    res = json.loads(out.read_text())["results"]
    assert set(res) == {"hierarchical", "decentralized", "ic3net"}
    for method, r in res.items():
        assert r["device"]["device"] == "cuda" and r["cpu"]["device"] == "cpu"
        assert r["device"]["env_steps"] == r["cpu"]["env_steps"] > 0
        assert r["device"]["team_return"] == r["cpu"]["team_return"]  # simulated: the cpu's numbers
        assert r["ratio"] > 0 and method in printed
