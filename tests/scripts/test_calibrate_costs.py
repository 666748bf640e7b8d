"""scripts/calibrate_costs.py: rates and estimate-vs-realized of a run; bad folders are one line."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("calibrate_costs", ROOT / "scripts" / "calibrate_costs.py")
calibrate = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(calibrate)


@pytest.mark.parametrize("args", [["{missing}"], ["{paper}", "--exclude-run", "{missing}"]])
def test_main__a_folder_without_a_store_is_one_line_and_status_2(args: list[str], tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    paths = {"missing": str(tmp_path / "nothing"), "paper": str(ROOT / "reproduction" / "paper")}
    monkeypatch.setattr(sys, "argv", ["calibrate_costs.py", *(a.format(**paths) for a in args)])
    assert calibrate.main() == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"calibrate_costs: no results store at {paths['missing']!r}: cells.parquet not found"]


def test_main__prints_rates_and_the_estimate_against_realized(monkeypatch: pytest.MonkeyPatch,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(sys, "argv", ["calibrate_costs.py", str(ROOT / "reproduction" / "ablation")])
    assert calibrate.main() == 0
    out = capsys.readouterr().out
    assert "hierarchical N=40 train: " in out
    assert "  all: 27 cells, estimated " in out  # every done cell of the ablation run
