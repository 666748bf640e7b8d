"""Output paths never replace what the bench did not write, and written files follow the
umask (D7 report --out, D9 replay --out and GIF permissions)."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from envs.render import write_gif
from tests.bench.conftest import one_error_line, run_cli, snapshot


def test_report_out__an_existing_file_is_one_line_and_stays(
        capsys: pytest.CaptureFixture[str], one_cell_run: Path, tmp_path: Path) -> None:
    victim = tmp_path / "notes.txt"
    victim.write_text("mine\n")
    code, _, err = run_cli(capsys, "report", "--run", str(one_cell_run), "--out", str(victim))
    assert code == 2
    one_error_line(err, "notes.txt", "is an existing file")
    assert victim.read_text() == "mine\n"


def test_report_out__a_folder_of_other_files_needs_force(
        capsys: pytest.CaptureFixture[str], one_cell_run: Path, tmp_path: Path) -> None:
    site = tmp_path / "site"
    site.mkdir()
    (site / "index.html").write_text("<p>my page</p>")
    before = snapshot(site)
    code, _, err = run_cli(capsys, "report", "--run", str(one_cell_run), "--out", str(site))
    assert code == 2
    one_error_line(err, "holds files the bench did not write", "--force")
    assert snapshot(site) == before
    code, _, err = run_cli(capsys, "report", "--run", str(one_cell_run), "--out", str(site), "--force")
    assert code == 0, err
    # a report folder of the bench is rebuilt without --force
    code, _, err = run_cli(capsys, "report", "--run", str(one_cell_run), "--out", str(site))
    assert code == 0, err


def test_replay_out__an_existing_file_is_refused_unless_force(
        capsys: pytest.CaptureFixture[str], one_cell_run: Path, tmp_path: Path) -> None:
    import pandas as pd

    cell = str(pd.read_parquet(one_cell_run / "cells.parquet")["cell_id"][0])
    victim = tmp_path / "passwd"
    victim.write_text("root:x:0:0\n")
    code, _, err = run_cli(capsys, "replay", "--run", str(one_cell_run), "--cell", cell, "--out", str(victim))
    assert code == 2
    one_error_line(err, "passwd", "already exists", "--force")
    assert victim.read_text() == "root:x:0:0\n"


def test_gif__follows_the_umask_like_every_written_file(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        path = write_gif(np.zeros((2, 8, 8, 3), dtype=np.uint8), tmp_path / "a.gif")
    finally:
        os.umask(old)
    assert path.stat().st_mode & 0o777 == 0o644
