"""Every count a user types has an upper bound with its reason (D4), and the
bounds change no cell id."""
from __future__ import annotations

from pathlib import Path

import pytest

from bench.cli import main
from bench.design.cells import Cell
from bench.design.grids import default_seeds, grid_builders
from bench.design.limits import LIMITS
from envs.errors import BenchError
from tests.bench.conftest import snapshot, toy_spec, write_grid_file


def _cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as exc:
        main(list(args))
    out, err = capsys.readouterr()
    return int(exc.value.code or 0), out, err


@pytest.mark.parametrize("field", ["eval_episodes", "episodes", "horizon", "n_robots", "groups", "ref_size",
                                   "search_radius", "c_max"])
def test_cell__a_count_above_its_bound_is_refused_with_the_reason(toy: str, field: str) -> None:
    top, why = LIMITS[field]
    with pytest.raises(BenchError, match=rf"{field}: Input should be less than or equal to {top} \(limit {top}: "):
        Cell.make(**toy_spec(**{field: top + 1}))
    assert why


def test_grid_file__huge_eval_episodes_is_refused_by_grids_and_run_and_nothing_is_written(
        capsys: pytest.CaptureFixture[str], toy: str, tmp_path: Path) -> None:
    grid_file = write_grid_file(tmp_path / "g.toml", toy_spec(eval_episodes=10**12), {"seed": [0]})
    for args in (["grids", "--grid-file", str(grid_file)],
                 ["run", "--grid-file", str(grid_file), "--out", str(tmp_path / "run")]):
        code, _, err = _cli(capsys, *args)
        assert code == 2 and err.count("\n") == 1, err
        assert "eval_episodes" in err and "driver holds" in err and "g.toml" in err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("args", [
    ["run", "--grid", "smoke", "--seeds", "100000"],
    ["grids", "--seeds", "100000"],
    ["run", "--grid", "smoke", "--workers", "100000"],
    ["tune", "--study", "s", "--trials", "1000000000", "--inline"],
    ["tune", "--study", "s", "--eval-episodes", "1000000000000", "--inline"],
    ["eval", "--method", "pibt", "--episodes", "1000000000000"],
])
def test_cli__a_huge_count_is_one_line_naming_option_and_reason(
        capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, args: list[str]) -> None:
    monkeypatch.chdir(tmp_path)
    before = snapshot(tmp_path)
    code, _, err = _cli(capsys, *args)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert "limit" in err and ("too large" in err or "less than or equal" in err), err
    assert snapshot(tmp_path) == before


def test_bounds__admit_every_built_in_grid_cell() -> None:
    """The committed runs' ids are checked in tests/reproduction; here: no built-in cell is
    near a bound, at five seeds."""
    for name, make in grid_builders().items():
        assert len(make(max(5, default_seeds(name))).cells) > 0
