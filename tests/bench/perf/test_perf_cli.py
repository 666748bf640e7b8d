"""The CLI turn-around suite (bench perf --suite cli) builds its table: one row per command
with its wall times and exit status (what it measures is not asserted: no timed tests)."""
from __future__ import annotations

from pathlib import Path

import pytest

from bench.perf import cli as perf_cli


def test_cli_suite__one_row_per_command_with_its_exit_status(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setattr(perf_cli, "COMMANDS", {"startup": None, "help": ["--help"],
                                               "error_method": ["eval", "--method", "pibtt"]})
    df = perf_cli.run_cli_suite(repeats=1, reproduction=tmp_path)  # no committed runs there: no --against row
    assert list(df["command"]) == ["startup", "help", "error_method"] and (df["suite"] == "cli").all()
    assert list(df["exit"]) == [0, 0, 2]
    assert (df["min_s"] > 0).all() and (df["median_s"] >= df["min_s"]).all()
