"""Without a terminal a run logs one line per finished or failed cell and a periodic summary;
--verbose prints every event."""
from __future__ import annotations

import io
import subprocess
from pathlib import Path

import pytest

from bench.execute.progress import LogProgress, QuietLogProgress, Snapshot, make_progress
from tests.bench.conftest import REPO, cli_argv, toy_spec, write_grid_file


def test_quiet_log__prints_the_start_finished_and_failed_cells_and_a_periodic_summary(
        monkeypatch: pytest.MonkeyPatch) -> None:
    clock = [0.0]
    monkeypatch.setattr("bench.execute.progress.time.monotonic", lambda: clock[0])
    buf = io.StringIO()
    log = QuietLogProgress(every_s=300.0, stream=buf)
    log.update(Snapshot(3, 0, 0, 0, 0.0, 0.0, kind="start"))
    for kind, msg in (("started", "started a"), ("train_chunk", "trained a: 8/16"), ("eval_chunk", "evaluated a"),
                      ("tick", "")):
        clock[0] += 10.0
        log.update(Snapshot(3, 0, 1, 0, 0.2, clock[0], message=msg, kind=kind))
    clock[0] += 10.0
    log.update(Snapshot(3, 1, 0, 0, 0.3, clock[0], message="done a", kind="done"))
    clock[0] += 301.0
    log.update(Snapshot(3, 1, 1, 0, 0.5, clock[0], kind="tick"))  # the periodic summary
    log.update(Snapshot(3, 1, 0, 1, 0.6, clock[0], message="failed b: boom", kind="failed"))
    lines = buf.getvalue().splitlines()
    assert len(lines) == 4
    assert "cells 0/3 done" in lines[0] and lines[1].endswith("| done a")
    assert "|" not in lines[2].split("ETA")[1] and lines[3].endswith("| failed b: boom")


def test_make_progress__quiet_without_terminal_unless_verbose(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CI", "true")
    assert isinstance(make_progress(), QuietLogProgress)
    verbose = make_progress(verbose=True)
    assert isinstance(verbose, LogProgress) and not isinstance(verbose, QuietLogProgress)


@pytest.mark.slow
def test_run__without_terminal_logs_at_most_one_line_per_cell_plus_start_and_summary(tmp_path: Path) -> None:
    grid = write_grid_file(tmp_path / "g.toml", toy_spec(episodes=16), {"seed": [0, 1, 2]})
    argv = cli_argv("run", "--grid-file", str(grid), "--out", str(tmp_path / "run"), "--workers", "2",
                    "--checkpoint-every", "1")
    quiet = subprocess.run(argv, cwd=REPO, capture_output=True, text=True, timeout=300)
    assert quiet.returncode == 0, quiet.stderr
    log = [ln for ln in quiet.stderr.splitlines() if ln.startswith("[")]
    assert 3 <= len(log) <= 3 + 2 and sum("| done " in ln for ln in log) == 3
