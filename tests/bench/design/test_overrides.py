"""bench run --set / --axis (bench/design/overrides.py): overrides of every cell, one-line
errors naming the option, and the resume rule (docs/decisions/0203)."""
from __future__ import annotations

import json
import subprocess

import pytest

from bench.design.grids import get_grid
from bench.design.overrides import apply_overrides, check_resume_overrides, parse_overrides
from envs.errors import BenchError
from tests.bench.conftest import cli_argv, toy_spec, write_grid_file


def test_set_and_axis_override_every_cell_of_the_smoke_grid() -> None:
    smoke = get_grid("smoke")
    grid = apply_overrides(smoke, parse_overrides(["horizon=32"], ["loss_p=0.1,0.3"]))
    assert {c.horizon for c in grid.cells} == {32}
    assert sorted({c.loss_p for c in grid.cells}) == [0.1, 0.3]
    assert len(grid.cells) == len(smoke.cells)  # p in {0.2, 0.6} replaced by {0.1, 0.3}
    assert {(c.method, c.n_robots) for c in grid.cells} == {(c.method, c.n_robots) for c in smoke.cells}
    assert "--set horizon=32 --axis loss_p=0.1,0.3" in grid.description


def test_overriding_a_field_with_its_own_value_keeps_every_cell_id() -> None:
    smoke = get_grid("smoke")
    same = apply_overrides(smoke, parse_overrides(["horizon=48"]))
    assert [c.cell_id for c in same.cells] == [c.cell_id for c in smoke.cells]
    assert apply_overrides(smoke, parse_overrides()) is smoke


def test_params_overrides_reach_the_method_hyperparameters() -> None:
    grid = apply_overrides(get_grid("smoke"), parse_overrides(["params.batch_episodes=4"]))
    assert {c.params["batch_episodes"] for c in grid.cells} == {4}


@pytest.mark.parametrize("sets,axes,message", [
    (["horizon"], [], r"--set 'horizon': expected KEY=VALUE"),
    (["horizn=32"], [], r"--set horizn=32: unknown cell field 'horizn'; choose from .*horizon"),
    ([], ["loss_p="], r"expected KEY=VALUE"),
    (["horizon=32"], ["horizon=16,32"], r"'horizon' is given twice"),
])
def test_malformed_or_unknown_overrides_are_one_line_errors(sets, axes, message) -> None:
    with pytest.raises(BenchError, match=message):
        parse_overrides(sets, axes)


@pytest.mark.parametrize("sets,axes,message", [
    (["horizon=abc"], [], r"^--set horizon=abc: .*horizon"),
    ([], ["loss_p=0.1,7"], r"^--axis loss_p=0.1,7: .*loss_p"),
    (["params.nope=1"], [], r"^--set params.nope=1: .*nope"),
])
def test_bad_values_name_the_option(sets, axes, message) -> None:
    with pytest.raises(BenchError, match=message):
        apply_overrides(get_grid("smoke"), parse_overrides(sets, axes))


def test_resuming_with_other_overrides_is_refused_and_the_same_ones_pass() -> None:
    made = parse_overrides(["horizon=32"])
    manifest = {"overrides": made}
    check_resume_overrides(manifest, parse_overrides(["horizon=32"]), "results/x")
    check_resume_overrides(None, made, "results/x")  # a new directory
    check_resume_overrides({}, parse_overrides(), "results/x")  # made before overrides existed: none
    with pytest.raises(BenchError, match=r"was run with --set horizon=32, this command gives no overrides"):
        check_resume_overrides(manifest, parse_overrides(), "results/x")
    with pytest.raises(BenchError, match=r"was run with no overrides, this command gives --set horizon=16"):
        check_resume_overrides({}, parse_overrides(["horizon=16"]), "results/x")


@pytest.mark.slow
def test_bench_run_records_its_overrides_and_refuses_other_ones_on_resume(tmp_path) -> None:
    grid = write_grid_file(tmp_path / "g.toml", toy_spec(episodes=2, eval_episodes=2), {"seed": [0]})
    out = tmp_path / "run"
    argv = cli_argv("run", "--grid-file", str(grid), "--out", str(out), "--workers", "1",
                    "--set", "horizon=8", "--axis", "loss_p=0.1,0.3")
    done = subprocess.run(argv, capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    manifest = json.loads((out / "manifest.json").read_text())
    want = {"set": {"horizon": 8}, "axis": {"loss_p": [0.1, 0.3]}}
    assert manifest["overrides"] == want and manifest["runs"][-1]["overrides"] == want
    assert "2/2 cells done" in done.stdout
    other = subprocess.run(argv[:-2] + ["--axis", "loss_p=0.5"], capture_output=True, text=True, check=False)
    assert other.returncode == 2 and other.stderr.count("\n") == 1, other.stderr
    assert "was run with --set horizon=8 --axis loss_p=0.1,0.3" in other.stderr
