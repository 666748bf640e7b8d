"""Never lose or touch what is not ours (SPEC 7): --fresh deletes only bench
files, run names are plain names, a full disk or a read-only run folder is one line, files
follow the umask, done cells are checked complete, bad cells and maps are refused.
All fast (no Ray): each case runs the CLI in-process or the store directly."""
from __future__ import annotations

import errno
import json
import os
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import torch

from bench.cli import main
from bench.design.cells import MAX_HORIZON, Cell
from bench.design.grid_files import load_grid_file
from bench.execute.plan import params_changes, plan_run
from bench.store import run_store as store_mod
from bench.store.checkpoints import load_checkpoint
from bench.store.completeness import expected_for_cell, incomplete_cells, stored_rows
from bench.store.run_store import RunStore, write_table
from envs.atomic import DiskFull, atomic_file
from envs.errors import BenchError
from reports.data.store import load_store
from tests.bench.conftest import (
    snapshot,
    store_with_params,
    toy_spec,
    write_finished_store,
    write_grid_file,
)


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
def finished(toy: str, tmp_path: Path) -> tuple[Path, Path]:
    """(grid file, finished run directory of two toy cells)."""
    grid_file = write_grid_file(tmp_path / "good.toml", toy_spec(), {"seed": [0, 1]})
    out = tmp_path / "run"
    write_finished_store(out, load_grid_file(grid_file))
    return grid_file, out


# ------------------------------------------------------------------ --fresh
def test_fresh__a_folder_without_manifest_is_refused_and_left_as_is(
        capsys: pytest.CaptureFixture[str], finished: tuple[Path, Path], tmp_path: Path) -> None:
    grid_file, _ = finished
    victim = tmp_path / "v"
    (victim / "train").mkdir(parents=True)
    (victim / "train" / "data.csv").write_text("precious\n")
    before = snapshot(victim)
    for extra in ([], ["--yes"]):
        code, _, err = _cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(victim), "--fresh", *extra)
        assert code == 2
        _one_line(err, "no manifest.json", "refusing to delete")
    assert snapshot(victim) == before


def test_fresh__wipe_deletes_only_files_the_bench_wrote(finished: tuple[Path, Path]) -> None:
    _, out = finished
    store = RunStore(out)
    cid = next(store.eval_dir.glob("*.parquet")).stem
    mine = {out / "notes.txt": "mine", out / "train" / "data.csv": "precious", out / "eval" / "extra.parquet": "x",
            out / "train" / cid / "my.parquet": "keep", out / "checkpoints" / "best.pt": "keep",
            out / "train" / "other" / "part-000000000.parquet": "not a cell id folder",
            out / "eval" / ".hidden.tmp": "not a bench temp name"}
    for path, text in mine.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    temp = out / "checkpoints" / f".{cid}.pt.abc123.tmp"  # a torn bench write: ours
    temp.write_bytes(b"torn")
    matrix_unit = out / "matrix" / cid / "n8-p0.2-bernoulli.parquet"  # bench matrix output: ours
    matrix_unit.parent.mkdir(parents=True)
    matrix_unit.write_bytes(b"unit")
    mine[out / "matrix" / "notes.md"] = "mine too"
    (out / "matrix" / "notes.md").write_text("mine too")
    bench_files = set(store.bench_files())
    assert temp in bench_files and matrix_unit in bench_files and not bench_files & set(mine)
    deleted = store.wipe()
    assert set(deleted) == bench_files
    assert {p: p.read_text() for p in mine} == mine, "a user file was touched"
    assert not store.manifest_path.exists() and not store.cells_path.exists()
    assert not any(p.suffix == ".pt" and p.name != "best.pt" for p in out.rglob("*"))
    assert not list(store.train_dir.glob("*/part-*.parquet")) or (out / "train" / "other").exists()


def test_fresh__non_interactive_without_yes_asks_for_it_and_changes_nothing(
        capsys: pytest.CaptureFixture[str], finished: tuple[Path, Path]) -> None:
    grid_file, out = finished
    before = snapshot(out)
    code, _, err = _cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(out), "--fresh")
    assert code == 2
    _one_line(err, "--fresh would delete the", "files the bench wrote", "pass --yes")
    assert snapshot(out) == before


# ---------------------------------------------------------------- run names
@pytest.mark.parametrize("name", ["../../victim", "/tmp/victim", "a/b", "..", ".hidden", "a\\\\b", ""])
def test_grid_file__a_name_that_is_a_path_is_refused_naming_file_and_field(
        capsys: pytest.CaptureFixture[str], toy: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        name: str) -> None:
    grid_file = write_grid_file(tmp_path / "shared.toml", toy_spec(), {"seed": [0]}, name=name)
    with pytest.raises(BenchError, match=r"grid file .*shared\.toml.*: name: .* is not a plain run name"):
        load_grid_file(grid_file)
    monkeypatch.chdir(tmp_path)  # the default --out would be results/<name>
    before = snapshot(tmp_path)
    code, _, err = _cli(capsys, "run", "--grid-file", str(grid_file), "--fresh", "--yes")
    assert code == 2
    _one_line(err, "shared.toml", "name")
    assert snapshot(tmp_path) == before and not (tmp_path / "results").exists()


def test_grid_file__a_plain_name_is_kept(toy: str, tmp_path: Path) -> None:
    grid_file = write_grid_file(tmp_path / "g.toml", toy_spec(), {"seed": [0]}, name="radius-sweep_2.v1")
    assert load_grid_file(grid_file).name == "radius-sweep_2.v1"


# ---------------------------------------------------------------- disk full
def _enospc(*_: object, **__: object) -> None:
    raise OSError(errno.ENOSPC, "No space left on device")


class _FullFile:
    """A file object whose write fails like a full disk after ``room`` bytes."""

    def __init__(self, fh: object, room: int) -> None:
        self.fh, self.room = fh, room

    def write(self, data: bytes) -> int:
        if len(data) > self.room:
            raise OSError(errno.ENOSPC, "No space left on device")
        self.room -= len(data)
        return self.fh.write(data)  # type: ignore[attr-defined]

    def __getattr__(self, name: str) -> object:
        return getattr(self.fh, name)

    def __enter__(self) -> _FullFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.fh.close()  # type: ignore[attr-defined]


@pytest.fixture
def full_disk(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every file opened by atomic_file (envs/atomic.py) fails its first write with ENOSPC."""
    import envs.atomic

    def full_open(path: str, *args: object, **kw: object) -> object:
        return _FullFile(open(path, *args, **kw), room=0)  # type: ignore[call-overload]

    monkeypatch.setattr(envs.atomic, "open", full_open, raising=False)


def test_disk_full__a_write_is_one_bench_error_and_the_old_file_stays(tmp_path: Path, full_disk: None) -> None:
    path = tmp_path / "cells.parquet"
    path.write_bytes(b"old")
    with pytest.raises(DiskFull) as exc:
        with atomic_file(path) as fh:
            fh.write(b"new")
    assert str(exc.value) == (f"disk full while writing {path}; nothing stored was damaged; "
                              "free space and rerun to resume")
    assert path.read_bytes() == b"old" and os.listdir(tmp_path) == ["cells.parquet"]


def test_disk_full__mid_run_checkpoint_save_names_the_checkpoint(tmp_path: Path, full_disk: None) -> None:
    store = RunStore(tmp_path)
    state = {"w": torch.zeros(1000)}  # torch.save fails inside its zip writer when not buffered
    with pytest.raises(DiskFull, match=r"disk full while writing .*checkpoints/0123456789ab\.pt; nothing stored"):
        store.write_checkpoint("0123456789ab", {"cell": "{}", "state": state})
    assert not any(store.ckpt_dir.iterdir())


def test_disk_full__at_start_and_in_report_is_one_line_exit_2(
        capsys: pytest.CaptureFixture[str], finished: tuple[Path, Path], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch, full_disk: None) -> None:
    grid_file, out = finished
    import envs.atomic

    monkeypatch.setattr(envs.atomic.tempfile, "mkstemp", _enospc)  # the one atomic writer
    before = snapshot(out)
    code, _, err = _cli(capsys, "report", "--run", str(out))
    assert code == 2
    _one_line(err, "disk full while writing", "report", "free space and rerun")
    assert snapshot(out) == before
    # at start: the run directory cannot be created (Ray is not needed to get there)
    import bench.execute.runner
    from bench.execute.ray_cluster import RayContext

    monkeypatch.setattr(bench.execute.runner, "connect", lambda *a, **k: RayContext(False, "none", 1))
    monkeypatch.setattr(Path, "mkdir", _enospc)
    code, _, err = _cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(tmp_path / "new"))
    assert code == 2
    _one_line(err, "disk full while writing", "new")


@pytest.fixture
def tiny_tmpfs(tmp_path: Path) -> Iterator[Path]:
    """A 256 KiB tmpfs (needs root and mount permission); skipped where it cannot be mounted."""
    mnt = tmp_path / "tmpfs"
    mnt.mkdir()
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root (CI runs unprivileged); ENOSPC is simulated above")
    res = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mnt)], capture_output=True)
    if res.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {res.stderr.decode().strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)  # lazy: a failed write may hold a file open


def test_disk_full__on_a_real_tiny_tmpfs_the_store_is_undamaged(
        capsys: pytest.CaptureFixture[str], finished: tuple[Path, Path], tiny_tmpfs: Path) -> None:
    _, out = finished
    import shutil

    run = tiny_tmpfs / "run"
    shutil.copytree(out, run, ignore=shutil.ignore_patterns("checkpoints"))
    vfs = os.statvfs(tiny_tmpfs)  # leave 32 KiB: the disk fills up in the middle of a write
    (tiny_tmpfs / "filler").write_bytes(b"\0" * max(vfs.f_bavail * vfs.f_frsize - 32 * 1024, 0))
    before = snapshot(run)
    store = RunStore(run)
    with pytest.raises(DiskFull, match="checkpoints/0123456789ab.pt"):
        store.write_checkpoint("0123456789ab", {"state": {"w": torch.zeros(200_000)}})  # > the disk
    code, _, err = _cli(capsys, "report", "--run", str(run))
    assert code == 2
    _one_line(err, "disk full while writing")
    assert {k: v for k, v in snapshot(run).items() if not k.startswith("report")} == before


# --------------------------------------------------------- files and umask
@pytest.mark.parametrize(("umask", "mode"), [(0o022, 0o644), (0o027, 0o640), (0o002, 0o664)])
def test_result_files__follow_the_umask(tmp_path: Path, umask: int, mode: int) -> None:
    import pyarrow as pa

    from reports.writers import write_text

    old = os.umask(umask)
    try:
        write_table(tmp_path / "t.parquet", pa.table({"a": [1]}))
        RunStore(tmp_path).write_manifest({"x": 1})
        write_text(tmp_path / "report" / "index.md", "hi")
    finally:
        os.umask(old)
    for p in (tmp_path / "t.parquet", tmp_path / "manifest.json", tmp_path / "report" / "index.md"):
        assert p.stat().st_mode & 0o777 == mode, p


# ----------------------------------------------------------- checkpoints
def test_checkpoint__a_pickled_object_is_refused_with_the_whole_reason(tmp_path: Path) -> None:
    path = tmp_path / "evil.pt"
    torch.save({"format": store_mod.CHECKPOINT_FORMAT, "x": _Payload()}, path)
    with pytest.raises(BenchError) as exc:
        load_checkpoint(path)
    msg = str(exc.value)
    assert "refusing checkpoint" in msg and "_Payload" in msg and "weights_only=True" in msg
    assert "weights_only=False" not in msg and "can still be loaded" not in msg and msg.endswith("by this bench")


class _Payload:
    pass


# ------------------------------------------------------------ completeness
def test_completeness__a_done_cell_missing_training_rows_is_trained_again(finished: tuple[Path, Path]) -> None:
    grid_file, out = finished
    grid = load_grid_file(grid_file)
    store = RunStore(out)
    cell = grid.cells[0]
    # 5 episodes x argmax, sample, sample@0.5
    assert expected_for_cell(cell).train == 8 and expected_for_cell(cell).eval == 15
    parts = store.train_parts(cell.cell_id)
    parts[1][1].unlink()  # a training part of a finished cell disappears
    states, _ = plan_run(store, grid, fresh=False)
    st = {s.cell_id: s for s in states}
    assert st[cell.cell_id].phase == "pending" and not st[cell.cell_id].has_checkpoint
    assert st[cell.cell_id].rerun == "was done but 4 of 8 training rows stored; training it again from the start"
    assert st[grid.cells[1].cell_id].phase == "done" and st[grid.cells[1].cell_id].rerun == ""


def test_completeness__a_done_cell_missing_eval_rows_is_evaluated_again_from_its_checkpoint(
        finished: tuple[Path, Path]) -> None:
    grid_file, out = finished
    grid = load_grid_file(grid_file)
    store = RunStore(out)
    cid = grid.cells[1].cell_id
    table = pq.read_table(store.eval_path(cid))
    pq.write_table(table.slice(0, 3), store.eval_path(cid))  # keeps the footer metadata
    assert stored_rows(store, cid).eval == 3
    st = {s.cell_id: s for s in plan_run(store, grid, fresh=False)[0]}[cid]
    assert (st.phase, st.trained, st.has_checkpoint) == ("pending", True, True)
    assert st.rerun == ("was done but 3 of 5 evaluation episodes in execution mode argmax, 0 of 5 evaluation episodes "
                        "in execution mode sample, 0 of 5 evaluation episodes in execution mode sample@0.5 stored; "
                        "evaluating it again from its final checkpoint")


def test_completeness__report_warns_naming_the_incomplete_cell(
        capsys: pytest.CaptureFixture[str], finished: tuple[Path, Path], tmp_path: Path) -> None:
    grid_file, out = finished
    store = RunStore(out)
    cid = load_grid_file(grid_file).cells[0].cell_id
    store.train_parts(cid)[0][1].unlink()
    assert incomplete_cells(store, store.read_cells()) == {cid: "4 of 8 training rows"}
    code, _, err = _cli(capsys, "report", "--run", str(out), "--out", str(tmp_path / "rep"))
    assert code == 0
    assert f"bench: warning: cell {cid} is done but its rows are incomplete: 4 of 8 training rows" in err
    assert f"cell {cid} is done but its rows are incomplete" in (tmp_path / "rep" / "index.md").read_text()


# ------------------------------------------------------------ report --out
def test_report__out_writes_elsewhere_and_leaves_the_run_unchanged(
        capsys: pytest.CaptureFixture[str], finished: tuple[Path, Path], tmp_path: Path) -> None:
    _, out = finished
    before = snapshot(out)
    code, stdout, err = _cli(capsys, "report", "--run", str(out), "--out", str(tmp_path / "elsewhere"))
    assert code == 0, err
    assert (tmp_path / "elsewhere" / "index.html").exists() and "elsewhere" in stdout
    assert snapshot(out) == before


@pytest.fixture
def read_only_run(finished: tuple[Path, Path], tmp_path: Path) -> Iterator[Path]:
    """A copy of the finished run on a read-only file system (root: a tmpfs remounted ro)
    or with every write permission removed (unprivileged)."""
    _, out = finished
    if os.geteuid() != 0:
        import shutil

        ro = tmp_path / "ro"
        shutil.copytree(out, ro)
        for p in [ro, *ro.rglob("*")]:
            p.chmod(p.stat().st_mode & ~0o222)
        yield ro
        for p in [ro, *ro.rglob("*")]:
            p.chmod(p.stat().st_mode | 0o200)
        return
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=8m", "tmpfs", str(mnt)], capture_output=True).returncode:
        pytest.skip("root without mount permission: cannot make a read-only folder")
    try:
        subprocess.run(["cp", "-r", str(out), str(mnt / "run")], check=True)
        subprocess.run(["mount", "-o", "remount,ro", str(mnt)], check=True)
        yield mnt / "run"
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)  # lazy: a failed write may hold a file open


def test_report__a_read_only_run_without_out_is_one_line_suggesting_out(
        capsys: pytest.CaptureFixture[str], read_only_run: Path, tmp_path: Path) -> None:
    before = snapshot(read_only_run)
    code, _, err = _cli(capsys, "report", "--run", str(read_only_run))
    assert code == 2
    _one_line(err, "is read-only", "--out DIR")
    code, _, err = _cli(capsys, "report", "--run", str(read_only_run), "--out", str(tmp_path / "rep"))
    assert code == 0, err
    assert (tmp_path / "rep" / "index.html").exists() and snapshot(read_only_run) == before


# -------------------------------------------------------- cells and maps
@pytest.mark.parametrize(("field", "value", "message"), [
    ("n_robots", True, "n_robots: Input should be a valid integer"),
    ("seed", 1.0, "seed: Input should be a valid integer"),
    ("horizon", 10**12, f"horizon: Input should be less than or equal to {MAX_HORIZON}"),
    ("safety_filter", 1, "safety_filter: Input should be a valid boolean"),
    ("loss_p", True, "loss_p: Input should be a valid number"),
])
def test_cell__non_integers_and_huge_horizons_are_refused(toy: str, field: str, value: object, message: str) -> None:
    with pytest.raises(BenchError, match=message):
        Cell.make(**toy_spec(**{field: value}))


def test_cell__an_integer_is_still_a_valid_loss_probability(toy: str) -> None:
    assert Cell.make(**toy_spec(loss_p=0)).loss_p == 0.0


@pytest.mark.parametrize(("rows", "message"), [
    (["@@@@", "@@@@", "@@@@"], "has no free cells (all 3x4 cells are obstacles); 4 robots need at least 4"),
    (["@@@@", "@..@", "@@@@"], "4 robots do not fit layout"),
])
def test_map__without_enough_free_cells_is_a_clear_error_for_run_and_eval(
        capsys: pytest.CaptureFixture[str], toy: str, tmp_path: Path, rows: list[str], message: str) -> None:
    path = tmp_path / "blocked.map"
    path.write_text("type octile\nheight 3\nwidth 4\nmap\n" + "\n".join(rows) + "\n")
    with pytest.raises(BenchError, match="layout"):
        Cell.make(**toy_spec(layout=str(path)))
    code, _, err = _cli(capsys, "eval", "--method", "pibt", "--n-robots", "4", "--layout", str(path), "--episodes", "1")
    assert code == 2
    _one_line(err, message)
    grid_file = write_grid_file(tmp_path / "g.toml", toy_spec(layout=str(path)), {"seed": [0]})
    code, _, err = _cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(tmp_path / "run"))
    assert code == 2
    _one_line(err, message, "g.toml")
    assert not (tmp_path / "run").exists()


def test_manifest_json_is_plain_json(finished: tuple[Path, Path]) -> None:
    _, out = finished
    assert json.loads((out / "manifest.json").read_text())["grid"] == "toygrid"


# ------------------------------------------------- a default changed since
def test_changed_default__a_resume_is_refused_naming_cell_and_field_and_nothing_changes(
        capsys: pytest.CaptureFixture[str], finished: tuple[Path, Path]) -> None:
    grid_file, out = finished
    cid = load_grid_file(grid_file).cells[1].cell_id
    store_with_params(out, cid, lr=0.01, gone=None)
    before = snapshot(out)
    code, _, err = _cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(out))
    assert code == 2
    _one_line(err, "1 stored cell(s)", f"{cid} (toy N=4 p=0.2 seed=1): gone: null -> (absent), lr: 0.01 -> 0.05. ",
              "--rerun-changed", "superseded/")
    assert snapshot(out) == before


def test_changed_default__rerun_changed_plans_only_that_cell_again_from_the_start(finished: tuple[Path, Path]) -> None:
    grid_file, out = finished
    grid = load_grid_file(grid_file)
    store_with_params(out, grid.cells[0].cell_id, lr=0.01, removed_field=3)
    states = {s.cell_id: s for s in plan_run(RunStore(out), grid, fresh=False, rerun_changed=True)[0]}
    st, other = states[grid.cells[0].cell_id], states[grid.cells[1].cell_id]
    assert (st.phase, st.trained, st.has_checkpoint, st.episodes_done) == ("pending", False, False, 0)
    assert st.superseded is not None and json.loads(st.superseded["params_json"])["lr"] == 0.01
    assert st.rerun == ("was stored with other method parameters (lr: 0.01 -> 0.05; removed_field: 3 -> "
                        "(absent)); its files moved to superseded/, training it again from the start")
    assert other.phase == "done" and other.superseded is None and other.rerun == ""


def test_changed_default__a_cell_without_stored_results_is_not_a_conflict(finished: tuple[Path, Path]) -> None:
    grid_file, out = finished
    grid = load_grid_file(grid_file)
    cid = grid.cells[0].cell_id
    store = RunStore(out)
    for _, part in store.train_parts(cid):
        part.unlink()
    store.eval_path(cid).unlink()
    store.ckpt_path(cid).unlink()
    store_with_params(out, cid, lr=0.01)  # e.g. a pending row written by an earlier run
    st = {s.cell_id: s for s in plan_run(store, grid, fresh=False)[0]}[cid]
    assert st.phase == "pending" and st.superseded is None and st.rerun == ""
    assert params_changes("nan", grid.cells[0]) == params_changes("", grid.cells[0]) == []  # no parameters stored


def test_supersede__moves_every_file_of_the_cell_and_keeps_its_row(finished: tuple[Path, Path]) -> None:
    grid_file, out = finished
    grid = load_grid_file(grid_file)
    cid, keep = grid.cells[0].cell_id, grid.cells[1].cell_id
    store = RunStore(out)
    (out / "matrix" / cid).mkdir(parents=True)
    (out / "matrix" / cid / "n4-p0.2.parquet").write_bytes(b"rows")
    before = snapshot(out)
    row = store.read_cells().set_index("cell_id").loc[cid].to_dict()
    row["params_json"] = json.dumps({**json.loads(row["params_json"]), "lr": 0.01})  # as run before
    dest = store.supersede(cid, {"cell_id": cid, **row}, "20261202T000000Z")
    assert dest == out / "superseded" / f"{cid}-20261202T000000Z"
    moved = {k: v for k, v in before.items() if cid in k}
    after = snapshot(out)
    assert not any(cid in k and not k.startswith("superseded/") for k in after)  # nothing of it left in place
    assert {k for k in after if k.startswith("superseded/")} == {
        f"superseded/{dest.name}/{name}" for name in (
            *(f"train/{Path(k).name}" for k in moved if k.startswith("train/")),
            "eval.parquet", "checkpoint.pt", "matrix/n4-p0.2.parquet", "cells_row.json")}
    assert sorted(after[f"superseded/{dest.name}/train/{Path(k).name}"] for k in moved if k.startswith("train/")) == \
        sorted(v for k, v in moved.items() if k.startswith("train/"))  # moved, byte for byte
    assert json.loads(after[f"superseded/{dest.name}/cells_row.json"])["cell_id"] == cid
    assert {k: v for k, v in after.items() if keep in k} == {k: v for k, v in before.items() if keep in k}
    assert not store.has_results(cid) and store.has_results(keep)
    assert cid not in set(store.read_train()["cell_id"]) and cid not in set(store.read_eval()["cell_id"])
    notes = [p for p in load_store(out).problems if "superseded" in p]  # the report says what was redone
    assert notes == [f"superseded/{dest.name}: toy N=4 p=0.2 seed=0 was trained again with other parameters "
                     "(lr: 0.01 -> 0.05); its former rows are kept there, not shown"]


def test_changed_default__a_field_the_stored_row_lacks_and_many_cells_in_one_message(toy: str, tmp_path: Path) -> None:
    grid_file = write_grid_file(tmp_path / "seven.toml", toy_spec(episodes=2, eval_episodes=1),
                                {"seed": list(range(7))})
    grid = load_grid_file(grid_file)
    out = tmp_path / "run"
    write_finished_store(out, grid)
    store = RunStore(out)
    cells = store.read_cells()
    cells["params_json"] = [json.dumps({k: v for k, v in json.loads(js).items() if k != "marker"}, sort_keys=True)
                            for js in cells["params_json"]]  # written before the field existed
    store.write_cells(cells.to_dict("records"))
    with pytest.raises(BenchError) as exc:
        plan_run(store, grid, fresh=False)
    msg = str(exc.value)
    assert msg.startswith(f"{out}: 7 stored cell(s) were run with other method parameters")
    assert msg.count('marker: (absent) -> ""') == 5 and "; and 2 more. Resuming" in msg


def test_params_changes__a_parameter_added_later_is_a_change_only_off_its_default() -> None:
    cell = Cell.make(method="decentralized", n_robots=8, loss_p=0.2, layout="tiny")
    stored = cell.method_params().model_dump(mode="json")
    del stored["protocol"]  # a cell trained before the parameter existed (decision 0216)
    assert params_changes(json.dumps(stored), cell) == []
    mappo = Cell.make(method="decentralized", n_robots=8, loss_p=0.2, layout="tiny", params={"protocol": "mappo"})
    assert params_changes(json.dumps(stored), mappo) == ["protocol: (absent) -> \"mappo\""]
    stored["protocol"] = "mappo"  # a stored value other than today's is a change, default or not
    assert params_changes(json.dumps(stored), cell) == ["protocol: \"mappo\" -> \"paper\""]
