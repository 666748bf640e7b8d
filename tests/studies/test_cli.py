"""``bench tune`` end to end with the fake method, inline (runtime ~5 s)."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from bench.cli import main

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

TINY = ["--method", "fake_hier", "--n-robots", "4", "--horizon", "16", "--episodes", "8",
        "--eval-episodes", "10", "--inline", "--workers", "2"]


def _bench(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as exc:
        main(args)
    out = capsys.readouterr()
    return int(exc.value.code or 0), out.out, out.err


SMALL = ["--param", "ref_size=2,32", "--param", "search_radius=1"]  # 2 configurations


def test_cli__tune_runs_resumes_and_prints_the_best_as_a_grid_file(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _bench(["tune", "--study", "demo", "--trials", "3", "--out", str(tmp_path), *TINY, *SMALL],
                            capsys)
    assert code == 0, err
    assert "3/3 finished trials" in out and "reason:" in out
    assert "best: withheld, no best configuration yet: 1 of 2 configurations have 2 finished" in out
    assert "[3/3 finished, " in err and "ETA" in err  # progress on every finished trial
    assert (tmp_path / "demo" / "trials.parquet").exists()
    assert (tmp_path / "demo" / "report" / "study_landscape.png").exists()
    code, _out, err = _bench(["tune", "--best", "demo", "--out", str(tmp_path)], capsys)
    assert code == 2 and "no best configuration yet" in err
    # resume: omitted options come from the study; the default count completes the grid
    code, out, err = _bench(["tune", "--study", "demo", "--out", str(tmp_path), "--inline"], capsys)
    assert code == 0, err
    assert "4/4 finished trials" in out and "1 run now" in out
    assert "best: ref_size=32, search_radius=1: mean objective" in out and "over 2 replicates" in out
    code, out, err = _bench(["tune", "--best", "demo", "--out", str(tmp_path)], capsys)
    assert code == 0, err
    grid = tomllib.loads(out)
    assert grid["base"]["method"] == "fake_hier" and grid["base"]["n_robots"] == 4
    assert (grid["base"]["ref_size"], grid["base"]["search_radius"]) == (32, 1)


def test_cli__resuming_with_a_different_setting_is_one_clear_error(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _bench(["tune", "--study", "d", "--trials", "1", "--out", str(tmp_path), *TINY], capsys)[0] == 0
    code, _out, err = _bench(["tune", "--study", "d", "--trials", "2", "--out", str(tmp_path),
                              "--n-robots", "6", "--inline"], capsys)
    assert code == 2
    assert err.count("\n") == 1 and "created with n_robots=4, not 6" in err


@pytest.mark.parametrize("args, message", [
    (["--param", "radius=1"], "unknown study parameter 'radius'"),
    (["--param", "ref_size="], "empty range"),
    (["--param", "search_radius=3..1"], "empty range"),
    (["--storage", "sqlite:////nonexistent-dir/x/study.db"], "cannot open study storage sqlite:"),
    (["--storage", "postgresql://user:secret@127.0.0.1:1/db"], "cannot open study storage postgresql://user:***@"),
    (["--storage", "nosuchdb://host/db"], "cannot open study storage nosuchdb:"),
    (["--objectives", "speed"], "objectives"),
    (["--trials", "0"], "--trials must be >= 1"),
    (["--search", "random"], "unknown search 'random'"),
    (["--replicates", "0"], "--replicates must be >= 1"),
    (["--prune-warmup", "1.5"], "--prune-warmup must be in [0, 1]"),
    (["--prune-min-rho", "2"], "--prune-min-rho must be in [-1, 1]"),
])
def test_cli__bad_input_is_one_line_on_stderr_and_exit_2(
        args: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _bench(["tune", "--study", "bad", "--out", str(tmp_path), *TINY, *args], capsys)
    assert code == 2
    assert err.count("\n") == 1 and message in err, err
    assert "secret" not in err and "Traceback" not in err
    assert not (tmp_path / "bad").exists()  # nothing written for a mistake


def test_cli__best_of_an_unknown_study_is_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _out, err = _bench(["tune", "--best", "nope", "--out", str(tmp_path)], capsys)
    assert code == 2 and "no study 'nope'" in err


def test_cli__tune_help_works(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _err = _bench(["tune", "--help"], capsys)
    assert code == 0
    for option in ("--study", "--trials", "--n-robots", "--loss-p", "--layout", "--episodes",
                   "--horizon", "--storage", "--objectives", "--c-max", "--seed", "--workers",
                   "--address", "--best", "--search", "--replicates", "--prune-warmup", "--prune-min-rho"):
        assert option in out
