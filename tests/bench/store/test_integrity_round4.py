"""Issue 52 (round four of fault injection), the store's side: checksums that cannot be
bypassed (D18 a link to an edited copy, D22 a deleted checksums.json), refusals that name
their file (D12 a file where eval/ belongs, D17 an unusable reference of --against, D21 an
export that cannot be written), and a Ray start that fails or is interrupted (D19, SIGTERM)
leaving one line and the store as it was. Fast: stores written in-process; Ray is never
started (its start is replaced by what Ray does when it fails or is signalled)."""
from __future__ import annotations

import errno
import os
import shutil
import signal
from pathlib import Path
from typing import Any

import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest

from bench.design.grid_files import load_grid_file
from bench.store.integrity import CHECKSUMS_FILE
from reports.data.store import load_store
from tests.bench.conftest import one_error_line, run_cli, snapshot, toy_spec, write_finished_store, write_grid_file


@pytest.fixture
def recorded(toy: str, tmp_path: Path) -> tuple[Path, Path, list[str]]:
    """(grid file, finished run of two toy cells with checksums recorded, cell ids)."""
    grid_file = write_grid_file(tmp_path / "good.toml", toy_spec(), {"seed": [0, 1]})
    out = tmp_path / "run"
    grid = load_grid_file(grid_file)
    write_finished_store(out, grid, checksums=True)
    return grid_file, out, [c.cell_id for c in grid.cells]


def edited_copy(src: Path, dest: Path) -> Path:
    """``src`` with team_return set to 999.0, written by pyarrow with its metadata kept."""
    table = pq.read_table(src)
    i = table.schema.get_field_index("team_return")
    table = table.set_column(i, "team_return", pc.add(pc.multiply(table["team_return"], 0.0), 999.0))
    pq.write_table(table, dest)
    return dest


# ------------------------------------------------- D22: a deleted checksums.json
def test_d22_a_run_written_with_checksums_refuses_when_checksums_json_is_deleted(
        capsys: pytest.CaptureFixture[str], recorded, tmp_path: Path) -> None:
    grid_file, out, (a, b) = recorded
    victim = out / "eval" / f"{b}.parquet"
    edited_copy(victim, victim)
    (out / CHECKSUMS_FILE).unlink()
    before = snapshot(out)
    code, _, err = run_cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(out))
    assert code == 2
    one_error_line(err, "checksums.json is missing although the manifest records", "--repair")
    assert snapshot(out) == before  # no new checksums.json over the edited file
    code, _, err = run_cli(capsys, "report", "--run", str(out), "--out", str(tmp_path / "rep"))
    assert code == 2
    one_error_line(err, "cells.parquet", "checksums.json is missing")
    assert not (tmp_path / "rep").exists()


def test_d22_report_against_such_a_reference_refuses(capsys: pytest.CaptureFixture[str], recorded,
                                                     tmp_path: Path) -> None:
    _, out, (a, b) = recorded
    ref = tmp_path / "ref"
    shutil.copytree(out, ref)
    edited_copy(ref / "eval" / f"{b}.parquet", ref / "eval" / f"{b}.parquet")
    (ref / CHECKSUMS_FILE).unlink()
    code, _, err = run_cli(capsys, "report", "--run", str(out), "--against", str(ref), "--out", str(tmp_path / "rep"))
    assert code == 2
    one_error_line(err, "checksums.json is missing")


# --------------------------------------------------- D18: a link to an edited copy
@pytest.mark.parametrize("edited", [True, False])
def test_d18_a_stored_file_replaced_by_a_link_is_refused_naming_where_it_points(
        capsys: pytest.CaptureFixture[str], recorded, tmp_path: Path, edited: bool) -> None:
    grid_file, out, (a, b) = recorded
    victim = out / "eval" / f"{b}.parquet"
    outside = tmp_path / "elsewhere.parquet"
    if edited:
        edited_copy(victim, outside)
    else:
        shutil.copyfile(victim, outside)  # the same bytes: still a link the bench does not follow
    victim.unlink()
    victim.symlink_to(outside)
    before = snapshot(out)
    code, _, err = run_cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(out))
    assert code == 2
    one_error_line(err, f"damaged file eval/{b}.parquet", f"a symbolic link to {outside} (outside the run)",
                   "--repair")
    assert snapshot(out) == before
    code, _, err = run_cli(capsys, "report", "--run", str(out), "--out", str(tmp_path / "rep"))
    assert code == 0, err
    warnings = [ln for ln in err.splitlines() if ln.startswith("bench: warning:")]
    assert len(warnings) == 1 and f"eval/{b}.parquet" in warnings[0] and "symbolic link" in warnings[0], err
    store = load_store(out)
    assert set(store.eval["cell_id"]) == {a} and 999.0 not in set(store.eval["team_return"])


def test_d18_a_linked_eval_folder_is_refused(capsys: pytest.CaptureFixture[str], recorded, tmp_path: Path) -> None:
    grid_file, out, _ = recorded
    shutil.move(out / "eval", tmp_path / "eval-elsewhere")
    (out / "eval").symlink_to(tmp_path / "eval-elsewhere")
    code, _, err = run_cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(out))
    assert code == 2
    one_error_line(err, "damaged file eval:", "symbolic link", "(outside the run)")


# ------------------------------------------------ D12: a file where eval/ belongs
def test_d12_a_file_where_eval_belongs_points_to_repair_in_report_and_run(
        capsys: pytest.CaptureFixture[str], recorded, tmp_path: Path) -> None:
    grid_file, out, _ = recorded
    shutil.rmtree(out / "eval")
    (out / "eval").write_text("not a folder\n")
    code, _, err = run_cli(capsys, "report", "--run", str(out), "--out", str(tmp_path / "rep"))
    assert code == 0, err
    assert "to complete it" not in err, err  # the dead end: `bench run` refused that
    assert "damaged file eval: a file stands where the bench keeps its folder eval/" in err and "--repair" in err
    before = snapshot(out)
    code, _, err = run_cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(out))
    assert code == 2
    one_error_line(err, "eval", "--repair")
    assert snapshot(out) == before


# ------------------------------------------- D17: --against an unusable reference
@pytest.mark.parametrize("damage", ["flipped", "deleted"])
def test_d17_against_a_reference_with_an_unusable_eval_file_names_it(
        capsys: pytest.CaptureFixture[str], toy: str, tmp_path: Path, damage: str) -> None:
    grid = load_grid_file(write_grid_file(tmp_path / "g.toml", toy_spec(), {"seed": [0]}))
    mine, ref = tmp_path / "mine", tmp_path / "ref"
    write_finished_store(mine, grid, checksums=True)
    shutil.copytree(mine, ref)
    cid = grid.cells[0].cell_id
    victim = ref / "eval" / f"{cid}.parquet"
    if damage == "flipped":
        data = bytearray(victim.read_bytes())
        data[len(data) // 2] ^= 0x10
        victim.write_bytes(bytes(data))
    else:
        victim.unlink()
    code, _, err = run_cli(capsys, "report", "--run", str(mine), "--against", str(ref),
                           "--out", str(tmp_path / "rep"))
    assert code == 2
    one_error_line(err, f"--against {ref}", f"eval/{cid}.parquet")


# --------------------------------------------------- D21: export cannot write
@pytest.mark.parametrize("fmt", ["marl-eval", "csv"])
def test_d21_export_to_a_read_only_file_system_is_one_line(
        capsys: pytest.CaptureFixture[str], recorded, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        fmt: str) -> None:
    import bench.export.command as command

    def read_only(path: Any) -> Any:
        raise OSError(errno.EROFS, "Read-only file system", str(path))

    monkeypatch.setattr(command, "atomic_file", read_only)
    _, out, _ = recorded
    target = tmp_path / ("x.json" if fmt == "marl-eval" else "csv")
    code, _, err = run_cli(capsys, "export", "--run", str(out), "--format", fmt, "--out", str(target))
    assert code == 2
    one_error_line(err, "cannot write", "Read-only file system")


# ------------------------------------------------ D19 and SIGTERM: Ray's start
@pytest.fixture
def ray_start(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """Ray's start replaced: ``box[0]`` is called instead of ``ray.init`` (no Ray, no token file)."""
    import ray

    from bench.execute import ray_cluster

    box: list[Any] = [None]
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "init", lambda *a, **k: box[0]())
    monkeypatch.setattr(ray, "shutdown", lambda *a, **k: None)
    monkeypatch.setattr(ray_cluster, "secure_token_file", lambda create: None)
    return box


def _timed_out() -> None:  # what Ray 2.60 raises when its node does not come up in time
    raise Exception("The current node timed out during startup. This could happen because some of the Ray "
                    "processes failed to startup.")


def test_d19_a_ray_start_that_times_out_is_one_line(
        capsys: pytest.CaptureFixture[str], toy: str, tmp_path: Path, ray_start: list[Any]) -> None:
    ray_start[0] = _timed_out
    grid_file = write_grid_file(tmp_path / "g.toml", toy_spec(), {"seed": [0]})
    code, _, err = run_cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(tmp_path / "run"))
    assert code == 2
    one_error_line(err, "could not start Ray on this machine", "timed out during startup", "rerun")


def test_d19_a_repair_whose_ray_start_fails_leaves_the_store_as_it_was(
        capsys: pytest.CaptureFixture[str], recorded, ray_start: list[Any]) -> None:
    ray_start[0] = _timed_out
    grid_file, out, (a, b) = recorded
    victim = out / "eval" / f"{b}.parquet"
    data = bytearray(victim.read_bytes())
    data[len(data) // 2] ^= 0x10
    victim.write_bytes(bytes(data))
    before = snapshot(out)
    code, _, err = run_cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(out), "--repair")
    assert code == 2
    one_error_line(err, "could not start Ray")
    assert snapshot(out) == before  # the damaged file is still in place, cells.parquet still consistent
    assert not (out / "superseded").exists()


def test_sigterm_while_ray_starts_is_exit_143_with_one_line(
        capsys: pytest.CaptureFixture[str], toy: str, tmp_path: Path, ray_start: list[Any]) -> None:
    def ray_init_signalled() -> None:  # Ray's init installs its handler, then the signal comes
        import ray._private.utils as ray_utils

        def ray_handler(signum: int, frame: Any) -> None:  # ray._private.worker.init's own
            raise SystemExit(signum)

        ray_utils.set_sigterm_handler(ray_handler)
        os.kill(os.getpid(), signal.SIGTERM)

    ray_start[0] = ray_init_signalled
    grid_file = write_grid_file(tmp_path / "g.toml", toy_spec(), {"seed": [0]})
    code, _, err = run_cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(tmp_path / "run"))
    assert code == 143, err
    one_error_line(err, "terminated")
