"""The `bench` CLI: every user mistake is one stderr line, exit status 2, store unchanged;
`bench eval` prints the eval table's metrics. Runtime: ~25 s (two subprocesses)."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import tomllib

from algorithms.common.episodes import EVAL_METRICS
from bench.cli import main
from bench.design import costs
from bench.design.grid_files import load_grid_file
from bench.design.grids import get_grid
from bench.store.run_store import RunStore
from tests.bench.conftest import (
    REPO,
    cli_argv,
    snapshot,
    toy_spec,
    write_finished_store,
    write_grid_file,
)

BENCH = str(Path(sys.executable).with_name("bench"))
ROOT = Path(__file__).resolve().parents[2]


def printed_scenarios(episodes: pd.DataFrame) -> list[str]:
    """The argmax rows' scenario hashes: every mode must show the same ones."""
    return episodes[episodes.execution == "argmax"]["scenario"].tolist()


def _cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as exc:
        main(list(args))
    out, err = capsys.readouterr()
    return int(exc.value.code or 0), out, err


@pytest.fixture
def store_dir(toy: str, tmp_path: Path) -> tuple[Path, Path]:
    """(grid file, finished run directory of that grid)."""
    grid_file = write_grid_file(tmp_path / "good.toml", toy_spec(), {"seed": [0, 1]})
    out = tmp_path / "run"
    write_finished_store(out, load_grid_file(grid_file))
    return grid_file, out


def _broken_copy(src: Path, dst: Path, how: str) -> Path:
    shutil.copytree(src, dst)
    store = RunStore(dst)
    if how == "version":
        manifest = json.loads(store.manifest_path.read_text())
        store.manifest_path.write_text(json.dumps({**manifest, "schema_version": 99}))
    elif how == "cells":
        store.cells_path.write_bytes(store.cells_path.read_bytes()[:300])
    elif how == "eval":
        path = next(store.eval_dir.glob("*.parquet"))
        path.write_bytes(b"PAR1 not really parquet")
    elif how == "part":
        path = next(store.train_dir.rglob("part-*.parquet"))
        path.write_bytes(path.read_bytes()[:-20])
    return dst


@pytest.mark.parametrize(("args", "message"), [
    (["run", "--grid", "nope"], "unknown grid 'nope'"),
    (["run"], "give exactly one of --grid"),
    (["run", "--grid-file", "{bad_method}"], "unknown method 'qmix'"),
    (["run", "--grid-file", "{bad_value}"], "n_robots"),
    (["run", "--grid-file", "{grid}", "--seeds", "0"], "--seeds"),
    (["run", "--grid-file", "{grid}", "--workers", "0"], "--workers"),
    (["run", "--grid-file", "{grid}", "--fresh"], "pass --yes to confirm"),
    (["run", "--grid-file", "{grid}", "--out", "{file}/sub"], "is not a directory"),
    (["run", "--grid-file", "{missing}"], "cannot read"),
    (["eval", "--method", "qmix"], "unknown method 'qmix'"),
    (["eval", "--method", "toy", "--loss-p", "2"], "--loss-p"),
    (["eval", "--method", "toy", "--n-robots", "4", "--layout", "nowhere.map"], "nowhere.map"),
    (["eval", "--checkpoint", "{out}/cells.parquet"], "corrupt checkpoint"),
    (["eval"], "give --method"),
    (["report", "--run", "{missing}"], "not a bench run directory"),
    (["replay", "--run", "{out}", "--cell", "nope"], "cell 'nope' is not in"),
    (["eval", "--method", "toy", "--n-robots", "4", "--layout", "tiny", "--execution", "argmx"],
     "unknown execution mode 'argmx'"),
    (["eval", "--method", "pibt", "--n-robots", "4", "--layout", "tiny", "--execution", "argmax"],
     "'argmax' does not apply to a planner"),
    (["replay", "--run", "{out}", "--cell", "{cell}", "--execution", "sample@0.25"],
     "was evaluated in argmax, sample, sample@0.5"),
    (["run", "--grid-file", "{bad_temp}"], "eval_temperatures: temperature 1 is the 'sample' mode"),
])
def test_cli__user_mistake_is_one_line_exit_2_and_the_store_is_unchanged(
        capsys: pytest.CaptureFixture[str], store_dir: tuple[Path, Path], tmp_path: Path,
        args: list[str], message: str) -> None:
    grid_file, out = store_dir
    (tmp_path / "bad_method.toml").write_text('[base]\nmethod = "qmix"\nn_robots = 4\nloss_p = 0.2\n')
    (tmp_path / "bad_value.toml").write_text('[base]\nmethod = "toy"\nloss_p = 0.2\n[axes]\nn_robots = [4, 0]\n')
    (tmp_path / "file").write_text("not a directory")
    (tmp_path / "bad_temp.toml").write_text('[base]\nmethod = "toy"\nn_robots = 4\nloss_p = 0.2\n'
                                            'layout = "tiny"\neval_temperatures = [1.0]\n')
    subst = dict(grid=grid_file, out=out, bad_method=tmp_path / "bad_method.toml",
                 bad_temp=tmp_path / "bad_temp.toml", cell=RunStore(out).read_cells()["cell_id"].iloc[0],
                 bad_value=tmp_path / "bad_value.toml", file=tmp_path / "file", missing=tmp_path / "missing.toml")
    argv = [a.format(**subst) for a in args]
    if argv[0] == "run" and "--out" not in argv:
        argv += ["--out", str(out)]
    before = snapshot(tmp_path)
    code, _, err = _cli(capsys, *argv)
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("bench: error: ") and message in err, err
    assert "Traceback" not in err
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("how", ["version", "cells", "eval", "part"])
def test_run__incompatible_or_corrupt_store_is_refused_unchanged(
        capsys: pytest.CaptureFixture[str], store_dir: tuple[Path, Path], tmp_path: Path, how: str) -> None:
    grid_file, out = store_dir
    broken = _broken_copy(out, tmp_path / f"broken-{how}", how)
    before = snapshot(broken)
    code, _, err = _cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(broken))
    assert code == 2 and err.count("\n") == 1, err
    assert {"version": "schema version 99", "cells": "corrupt Parquet", "eval": "corrupt Parquet",
            "part": "corrupt Parquet"}[how] in err
    assert snapshot(broken) == before


@pytest.mark.slow
def test_console_script__unreachable_address_exits_2_with_one_line(store_dir: tuple[Path, Path]) -> None:
    grid_file, out = store_dir
    before = snapshot(out)
    proc = subprocess.run(cli_argv("run", "--grid-file", str(grid_file), "--out", str(out),
                                   "--address", "127.0.0.1:1"),
                          cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "cannot reach Ray cluster at '127.0.0.1:1'" in proc.stderr
    assert snapshot(out) == before


@pytest.mark.slow
def test_console_script__unknown_grid_exits_2_and_version_names_the_commit() -> None:
    proc = subprocess.run([BENCH, "run", "--grid", "nope"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and proc.stderr.startswith("bench: error: ") and proc.stderr.count("\n") == 1
    ver = subprocess.run([BENCH, "--version"], capture_output=True, text=True, timeout=60)
    version = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert ver.returncode == 0 and ver.stdout.startswith(f"warehouse-marl-bench {version} (git ")


@pytest.mark.parametrize("method", ["toy", "decentralized"])
def test_eval__from_a_checkpoint_prints_the_rows_the_eval_table_stores(
        capsys: pytest.CaptureFixture[str], toy: str, tmp_path: Path, method: str) -> None:
    grid_file = write_grid_file(tmp_path / "g.toml", toy_spec(method=method, eval_episodes=5,
                                                               params={"batch_episodes": 2, "eval_chunk": 2}),
                                {"seed": [3]})
    out = tmp_path / "run"
    write_finished_store(out, load_grid_file(grid_file))
    store = RunStore(out)
    cell_id = store.read_cells()["cell_id"].iloc[0]
    code, stdout, err = _cli(capsys, "eval", "--checkpoint", str(store.ckpt_path(cell_id)), "--episodes", "5",
                             "--json")
    assert code == 0, err
    printed = json.loads(stdout)
    stored = store.read_eval()
    stored = stored[stored.cell_id == cell_id]
    assert printed["executions"] == ["argmax", "sample", "sample@0.5"] == list(printed["mean"])
    episodes = pd.DataFrame(printed["episodes"])
    for mode in printed["executions"]:
        want = stored[stored.execution == mode].sort_values("episode")
        got = episodes[episodes.execution == mode]
        assert list(printed["mean"][mode]) == list(EVAL_METRICS)
        assert printed["mean"][mode]["team_return"] == pytest.approx(want["team_return"].mean())
        assert printed["mean"][mode]["success_rate"] == pytest.approx(want["success_rate"].mean())
        for col in ("team_return", "collision_rate", "steps"):
            assert got[col].tolist() == pytest.approx(want[col].tolist()), (mode, col)
        assert got["scenario"].tolist() == want["scenario"].tolist() == printed_scenarios(episodes)
    code, stdout, err = _cli(capsys, "eval", "--checkpoint", str(store.ckpt_path(cell_id)), "--episodes", "5",
                             "--json", "--execution", "sample@0.5")
    assert code == 0 and json.loads(stdout)["executions"] == ["sample@0.5"]
    code, _, err = _cli(capsys, "eval", "--checkpoint", str(store.ckpt_path(cell_id)), "--execution", "sampel")
    assert code == 2 and err.count("\n") == 1 and "unknown execution mode 'sampel'" in err


def test_eval__untrained_initialization_prints_a_table(capsys: pytest.CaptureFixture[str], toy: str) -> None:
    code, stdout, err = _cli(capsys, "eval", "--method", "toy", "--n-robots", "4", "--layout", "tiny",
                             "--episodes", "3", "--horizon", "10")
    assert code == 0, err
    assert "untrained initialization" in stdout and "success_rate" in stdout and "payload_dec_per_step" in stdout
    assert all(mode in stdout for mode in ("argmax", "sample", "sample@0.5"))


def test_eval__options_override_the_checkpoints_cell(capsys: pytest.CaptureFixture[str], toy: str,
                                                    tmp_path: Path) -> None:
    """Each option replaces the checkpoint's value (a new N gets the layout sized for it);
    without a checkpoint the cell is N = 20, p = 0.2; a method other than the checkpoint's,
    or neither a method nor a checkpoint, is one line and status 2."""
    from envs.layouts import preset_for

    grid_file = write_grid_file(tmp_path / "g.toml", toy_spec(eval_episodes=2), {"seed": [3]})
    write_finished_store(tmp_path / "run", load_grid_file(grid_file))
    store = RunStore(tmp_path / "run")
    ckpt = str(store.ckpt_path(store.read_cells()["cell_id"].iloc[0]))
    code, stdout, err = _cli(capsys, "eval", "--checkpoint", ckpt, "--n-robots", "6", "--loss-p", "0.5", "--seed",
                             "9", "--horizon", "7", "--episodes", "3", "--execution", "argmax", "--json")
    assert code == 0, err
    printed = json.loads(stdout)
    cell = printed["cell"]
    assert (cell["method"], cell["n_robots"], cell["loss_p"], cell["seed"], cell["horizon"]) == ("toy", 6, 0.5, 9, 7)
    assert cell["layout"] == preset_for(6) and cell["episodes"] == 0 and cell["eval_episodes"] == 3
    assert len(printed["episodes"]) == 3 and max(r["steps"] for r in printed["episodes"]) <= 7
    code, stdout, err = _cli(capsys, "eval", "--method", "toy", "--layout", "tiny", "--episodes", "1",
                             "--horizon", "5", "--execution", "argmax", "--json")
    assert code == 0, err
    cell = json.loads(stdout)["cell"]
    assert (cell["n_robots"], cell["loss_p"], cell["seed"], cell["layout"]) == (20, 0.2, 0, "tiny")
    code, _, err = _cli(capsys, "eval", "--checkpoint", ckpt, "--method", "decentralized")
    assert code == 2 and err.count("\n") == 1
    assert "--method 'decentralized' does not match the checkpoint's method 'toy'" in err
    code, _, err = _cli(capsys, "eval")
    assert code == 2 and err == "bench: error: give --method (untrained initialization) or --checkpoint\n"
    code, _, err = _cli(capsys, "eval", "--checkpoint", ckpt, "--execution", "sampel")
    assert code == 2 and err.startswith("bench: error: --execution: unknown execution mode 'sampel'"), err


def test_eval__a_checkpoint_that_does_not_fit_the_settings_is_one_line(capsys: pytest.CaptureFixture[str],
                                                                       tmp_path: Path) -> None:
    grid_file = write_grid_file(tmp_path / "g.toml", toy_spec(method="decentralized", eval_episodes=2,
                                                               params={"batch_episodes": 2, "eval_chunk": 2}),
                                {"seed": [0]})
    write_finished_store(tmp_path / "run", load_grid_file(grid_file))
    store = RunStore(tmp_path / "run")
    ckpt = str(store.ckpt_path(store.read_cells()["cell_id"].iloc[0]))
    code, _, err = _cli(capsys, "eval", "--checkpoint", ckpt, "--set", "params.hidden=8", "--episodes", "1")
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"bench: error: checkpoint {ckpt!r} does not fit decentralized with these settings: ")
    assert "size mismatch" in err


def test_eval__set_overrides_what_the_evaluation_runs(capsys: pytest.CaptureFixture[str]) -> None:
    """--set reaches the evaluated method: without the safety filter the filter's rates are
    NaN; a hyperparameter lands in the printed cell; a bad key is one line, status 2."""
    base = ("eval", "--method", "hierarchical", "--n-robots", "4", "--layout", "tiny", "--episodes", "2",
            "--horizon", "8", "--execution", "argmax", "--json")
    code, stdout, err = _cli(capsys, *base, "--set", "params.fallback=per_robot")
    assert code == 0, err
    printed = json.loads(stdout)
    assert printed["cell"]["params"]["fallback"] == "per_robot"
    assert printed["mean"]["argmax"]["fallback_rate"] is not None
    code, stdout, err = _cli(capsys, *base, "--set", "safety_filter=false")
    assert code == 0, err
    assert json.loads(stdout)["mean"]["argmax"]["fallback_rate"] is None  # NaN: no filter ran
    code, _, err = _cli(capsys, *base, "--set", "fallback=per_robot")
    assert code == 2 and err.count("\n") == 1 and "unknown cell field 'fallback'" in err
    code, _, err = _cli(capsys, *base, "--set", "params.fallbak=per_robot")
    assert code == 2 and err.count("\n") == 1 and "fallbak" in err


@pytest.mark.parametrize("method", ["decentralized", "ic3net", "hierarchical"])
def test_methods__one_method_lists_its_presets_with_their_values(capsys: pytest.CaptureFixture[str],
                                                                 method: str) -> None:
    from algorithms.registry import method_class

    code, stdout, err = _cli(capsys, "methods", method, "--json")
    assert code == 0, err
    declared = method_class(method).presets["tuned"]
    source = f"studies/definitions/{method}.toml"
    assert json.loads(stdout)[0]["presets"]["tuned"] == {
        "values": dict(declared.values), "published": not declared.pending, "source": source}
    code, stdout, _ = _cli(capsys, "methods", method)
    assert code == 0 and f"{method} presets" in stdout
    assert ("(no published study yet)" if declared.pending else 'protocol="mappo"') in stdout


def test_methods__a_method_without_presets_prints_no_presets_table(capsys: pytest.CaptureFixture[str]) -> None:
    code, stdout, _ = _cli(capsys, "methods", "pibt")
    assert code == 0 and "hyperparameters" in stdout and "presets" not in stdout


def test_grids__lists_cell_counts_and_cost(capsys: pytest.CaptureFixture[str]) -> None:
    code, stdout, _ = _cli(capsys, "grids")
    assert code == 0
    rows = {line.split("│")[1].strip(): line for line in stdout.splitlines() if line.count("│") > 3}
    assert rows["smoke"].split("│")[2].strip() == "16"
    assert rows["paper"].split("│")[2].strip() == "84"  # 28 configurations x 3 seeds (default)
    assert [rows["paper"].split("│")[k].strip() for k in (6, 7)] == ["28", "3"]
    assert rows["full"].split("│")[2].strip() == "216"
    assert f"{costs.LABEL} on {costs.RATES_RUN}" in stdout  # where the rates come from, in the title
    assert costs.RATES_RUN == json.loads(costs.RATES_FILE.read_text())["run"] != ""
    hours = float(rows["paper"].split("│")[8])
    assert hours == pytest.approx(costs.grid_cell_hours(get_grid("paper").cells), rel=1e-2)
    code, stdout, _ = _cli(capsys, "grids", "--seeds", "5")
    five = {line.split("│")[1].strip(): line for line in stdout.splitlines() if line.count("│") > 3}
    assert five["paper"].split("│")[2].strip() == "140"
    assert float(five["paper"].split("│")[8]) == pytest.approx(hours * 5 / 3, rel=1e-2)


def test_grids__stack_seeds_and_a_runs_observed_rates(capsys: pytest.CaptureFixture[str]) -> None:
    from bench.design.cost_calibration import merged_rates, observed_costs, observed_rates

    run = Path(__file__).resolve().parents[2] / "reproduction" / "paper"
    code, stdout, err = _cli(capsys, "grids", "--stack-seeds", "3", "--rates-from", str(run))
    assert code == 0, err
    observed = observed_costs(run)
    assert f"rates of the {len(observed)} done cells of {run}" in " ".join(stdout.split())
    rows = {line.split("│")[1].strip(): line for line in stdout.splitlines() if line.count("│") > 3}
    expected = costs.grid_cell_hours(get_grid("paper").cells, merged_rates(observed_rates(observed)), 3)
    assert float(rows["paper"].split("│")[8]) == pytest.approx(expected, rel=1e-2)


def test_grids__rates_stack_seeds_scales_a_stacked_runs_rates_back_to_one_seed(
        capsys: pytest.CaptureFixture[str]) -> None:
    """The full grid ran with --stack-seeds 3: read that way, its hierarchical training rates
    are the one-seed ones the estimate then stacks once; without the option they are not."""
    from bench.design.cost_calibration import merged_rates, observed_costs, observed_rates

    run = Path(__file__).resolve().parents[2] / "reproduction" / "full"
    if not (run / "cells.parquet").is_file():
        pytest.skip("no committed full grid in this checkout")
    code, stdout, err = _cli(capsys, "grids", "--stack-seeds", "3", "--rates-from", str(run),
                             "--rates-stack-seeds", "3")
    assert code == 0, err
    assert "(made with --stack-seeds 3)" in " ".join(stdout.split())
    rows = {line.split("│")[1].strip(): line for line in stdout.splitlines() if line.count("│") > 3}
    one_seed = merged_rates(observed_rates(observed_costs(run, 3)))
    as_observed = merged_rates(observed_rates(observed_costs(run)))
    assert one_seed["hierarchical"]["train"][100] < as_observed["hierarchical"]["train"][100]
    expected = costs.grid_cell_hours(get_grid("full").cells, one_seed, 3)
    assert float(rows["full"].split("│")[8]) == pytest.approx(expected, rel=1e-2)
    code, _, err = _cli(capsys, "grids", "--rates-stack-seeds", "3")
    assert code == 2 and "--rates-stack-seeds" in err and "--rates-from" in err


def test_grids__rates_from_a_folder_without_done_cells_is_a_clear_error(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, _, err = _cli(capsys, "grids", "--rates-from", str(tmp_path))
    assert code == 2 and "--rates-from" in err and "cells.parquet not found" in err


def test_stack_seeds__auto_or_a_count_else_one_line_and_status_2(capsys: pytest.CaptureFixture[str],
                                                                 tmp_path: Path) -> None:
    """bench run and bench grids take --stack-seeds auto (bench run's default) or a count;
    anything else is refused in one line before a grid is built; bench grids estimates auto
    for one worker per CPU."""
    import os

    for command in (("run", "--grid", "smoke", "--out", str(tmp_path / "r")), ("grids",)):
        code, _, err = _cli(capsys, *command, "--stack-seeds", "two")
        assert code == 2 and err.strip().splitlines() == ["bench: error: --stack-seeds 'two': give auto or a "
                                                          "count of at least 1"], err
        assert not (tmp_path / "r").exists()
    code, stdout, err = _cli(capsys, "grids", "--stack-seeds", "auto")
    assert code == 0, err
    assert f"--stack-seeds auto with {os.cpu_count()} workers" in " ".join(stdout.split())
    rows = {line.split("│")[1].strip(): line for line in stdout.splitlines() if line.count("│") > 3}
    expected = costs.grid_cell_hours(get_grid("paper").cells, None, costs.AUTO, os.cpu_count() or 1)
    assert float(rows["paper"].split("│")[8]) == pytest.approx(expected, rel=1e-2)
    import inspect

    from bench.cli import run
    assert inspect.signature(run).parameters["stack_seeds"].default.default == "auto"
