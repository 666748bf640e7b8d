"""Output paths never replace what the bench did not write, and written files follow the
umask (issue 37, D7 report --out, D9 replay --out and GIF permissions)."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from bench.cli import main
from bench.grid_files import load_grid_file
from envs.render import write_gif
from tests.bench.conftest import snapshot, toy_spec, write_finished_store, write_grid_file


def _cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as exc:
        main(list(args))
    out, err = capsys.readouterr()
    return int(exc.value.code or 0), out, err


def _one_line(err: str, *needles: str) -> None:
    assert err.count("\n") == 1 and err.startswith("bench: error: ") and "Traceback" not in err, err
    for n in needles:
        assert n in err, err


@pytest.fixture
def run_dir(toy: str, tmp_path: Path) -> Path:
    grid = load_grid_file(write_grid_file(tmp_path / "g.toml", toy_spec(), {"seed": [0]}))
    write_finished_store(tmp_path / "run", grid)
    return tmp_path / "run"


def test_report_out__an_existing_file_is_one_line_and_stays(
        capsys: pytest.CaptureFixture[str], run_dir: Path, tmp_path: Path) -> None:
    victim = tmp_path / "notes.txt"
    victim.write_text("mine\n")
    code, _, err = _cli(capsys, "report", "--run", str(run_dir), "--out", str(victim))
    assert code == 2
    _one_line(err, "notes.txt", "is an existing file")
    assert victim.read_text() == "mine\n"


def test_report_out__a_folder_of_other_files_needs_force(
        capsys: pytest.CaptureFixture[str], run_dir: Path, tmp_path: Path) -> None:
    site = tmp_path / "site"
    site.mkdir()
    (site / "index.html").write_text("<p>my page</p>")
    before = snapshot(site)
    code, _, err = _cli(capsys, "report", "--run", str(run_dir), "--out", str(site))
    assert code == 2
    _one_line(err, "holds files the bench did not write", "--force")
    assert snapshot(site) == before
    code, _, err = _cli(capsys, "report", "--run", str(run_dir), "--out", str(site), "--force")
    assert code == 0, err
    # a report folder of the bench is rebuilt without --force
    code, _, err = _cli(capsys, "report", "--run", str(run_dir), "--out", str(site))
    assert code == 0, err


def test_replay_out__an_existing_file_is_refused_unless_force(
        capsys: pytest.CaptureFixture[str], run_dir: Path, tmp_path: Path) -> None:
    import pandas as pd

    cell = str(pd.read_parquet(run_dir / "cells.parquet")["cell_id"][0])
    victim = tmp_path / "passwd"
    victim.write_text("root:x:0:0\n")
    code, _, err = _cli(capsys, "replay", "--run", str(run_dir), "--cell", cell, "--out", str(victim))
    assert code == 2
    _one_line(err, "passwd", "already exists", "--force")
    assert victim.read_text() == "root:x:0:0\n"


def test_gif__follows_the_umask_like_every_written_file(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        path = write_gif(np.zeros((2, 8, 8, 3), dtype=np.uint8), tmp_path / "a.gif")
    finally:
        os.umask(old)
    assert path.stat().st_mode & 0o777 == 0o644
