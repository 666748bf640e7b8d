"""Integrity of stored results (D2 bit rot, D3 misplaced files, D8 manifest types,
D11 a way forward): every damaged or misplaced file is named in one line with the command
that repairs it; nothing is written before that. Fast: stores written in-process, no Ray
(the repair itself, which recomputes cells, is in test_repair.py)."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from bench.design.grid_files import load_grid_file
from bench.store.integrity import CHECKSUMS_FILE, Checksums, find_damage
from bench.store.run_store import RunStore, table_bytes
from envs.errors import BenchError
from reports.data.store import load_store
from tests.bench.conftest import (
    one_error_line,
    run_cli,
    snapshot,
    toy_spec,
    write_finished_store,
    write_grid_file,
)


@pytest.fixture
def recorded(toy: str, tmp_path: Path) -> tuple[Path, Path, list[str]]:
    """(grid file, finished run of two toy cells with checksums recorded, cell ids)."""
    grid_file = write_grid_file(tmp_path / "good.toml", toy_spec(), {"seed": [0, 1]})
    out = tmp_path / "run"
    grid = load_grid_file(grid_file)
    write_finished_store(out, grid, checksums=True)
    return grid_file, out, [c.cell_id for c in grid.cells]


@pytest.fixture
def legacy(toy: str, tmp_path: Path) -> tuple[Path, Path, list[str]]:
    """The same run written as by a bench without checksums (no checksums.json)."""
    grid_file = write_grid_file(tmp_path / "good.toml", toy_spec(), {"seed": [0, 1]})
    out = tmp_path / "old"
    grid = load_grid_file(grid_file)
    write_finished_store(out, grid)
    return grid_file, out, [c.cell_id for c in grid.cells]


def flip_bit(path: Path, where: float) -> None:
    data = bytearray(path.read_bytes())
    i = min(int(len(data) * where), len(data) - 1)
    data[i] ^= 0x10
    path.write_bytes(bytes(data))


def stored_files(out: Path, cid: str) -> dict[str, Path]:
    return {"cells": out / "cells.parquet", "eval": out / "eval" / f"{cid}.parquet",
            "train": sorted((out / "train" / cid).glob("part-*.parquet"))[0],
            "checkpoint": RunStore(out).ckpt_path(cid)}


# ------------------------------------------------------------------ recording
def test_checksums__every_stored_file_of_a_run_is_recorded_and_matches(recorded) -> None:
    _, out, ids = recorded
    data = json.loads((out / CHECKSUMS_FILE).read_text())
    recorded_files = set(data["files"])
    stored = {p.relative_to(out).as_posix() for p in RunStore(out).bench_files()} - {"manifest.json", CHECKSUMS_FILE}
    assert recorded_files == stored and len(stored) > 6
    assert find_damage(RunStore(out), RunStore(out).integrity()) == []


def test_checksums__page_checksums_change_no_row_value(recorded) -> None:
    _, out, ids = recorded
    import pyarrow as pa

    table = pq.read_table(out / "eval" / f"{ids[0]}.parquet")
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink)  # as before this change: no page checksums
    without = pq.read_table(pa.BufferReader(sink.getvalue()))
    with_crc = pq.read_table(pa.BufferReader(table_bytes(table)), page_checksum_verification=True)
    assert with_crc.to_pandas().equals(without.to_pandas()) and with_crc.schema.metadata == without.schema.metadata


# ---------------------------------------------------------------- D2: bit rot
@pytest.mark.parametrize("kind", ["cells", "eval", "train", "checkpoint"])
@pytest.mark.parametrize("where", [0.4, 0.97])  # data pages, footer
def test_bit_rot__run_refuses_naming_the_file_and_repair_and_writes_nothing(
        capsys: pytest.CaptureFixture[str], recorded, kind: str, where: float) -> None:
    grid_file, out, ids = recorded
    victim = stored_files(out, ids[1])[kind]
    flip_bit(victim, where)
    before = snapshot(out)
    code, _, err = run_cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(out))
    assert code == 2
    one_error_line(err, f"damaged file {victim.relative_to(out).as_posix()}", "--repair", "superseded/")
    assert snapshot(out) == before


def test_bit_rot__report_leaves_the_file_out_with_one_warning_and_no_wrong_number(
        capsys: pytest.CaptureFixture[str], recorded, tmp_path: Path) -> None:
    _, out, ids = recorded
    flip_bit(out / "eval" / f"{ids[1]}.parquet", 0.5)
    code, _, err = run_cli(capsys, "report", "--run", str(out), "--out", str(tmp_path / "rep"))
    assert code == 0, err
    warnings = [ln for ln in err.splitlines() if ln.startswith("bench: warning:")]
    assert len(warnings) == 1 and f"eval/{ids[1]}.parquet" in warnings[0] and "--repair" in warnings[0]
    store = load_store(out)
    assert set(store.eval["cell_id"]) == {ids[0]}  # the damaged cell's rows are not used
    assert any(f"damaged file eval/{ids[1]}.parquet" in p for p in store.problems)


def test_bit_rot__a_damaged_cells_parquet_stops_the_report_withone_error_line(
        capsys: pytest.CaptureFixture[str], recorded, tmp_path: Path) -> None:
    _, out, _ = recorded
    flip_bit(out / "cells.parquet", 0.5)
    code, _, err = run_cli(capsys, "report", "--run", str(out), "--out", str(tmp_path / "rep"))
    assert code == 2
    one_error_line(err, "damaged file cells.parquet", "--repair")


def test_bit_rot__in_a_store_without_checksums_a_data_page_flip_is_still_caught(
        capsys: pytest.CaptureFixture[str], legacy) -> None:
    """Parquet page checksums (written since this change) catch a flip in a data page even
    without checksums.json; the footer is covered only by checksums.json."""
    grid_file, out, ids = legacy
    victim = out / "eval" / f"{ids[0]}.parquet"
    meta = pq.read_metadata(victim)
    col = meta.row_group(0).column(meta.schema.names.index("team_return"))
    data = bytearray(victim.read_bytes())
    data[col.data_page_offset + col.total_compressed_size - 2] ^= 0x01  # inside the page's values
    victim.write_bytes(bytes(data))
    code, _, err = run_cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(out))
    assert code == 2
    one_error_line(err, f"damaged file eval/{ids[0]}.parquet", "--repair")


def test_checksums__a_rewrite_interrupted_between_checksums_and_rename_is_not_damage(recorded) -> None:
    """checksums.json is written before the file: a crash in between leaves the old file,
    whose digest the entry still accepts."""
    _, out, ids = recorded
    store = RunStore(out)
    checks = store.integrity()
    checks.start_recording()
    path = out / "cells.parquet"
    checks.before_write(path, b"the new bytes that never reached the disk")
    again = RunStore(out)
    assert find_damage(again, again.integrity()) == []


# ------------------------------------------------------------ D3: misplaced
@pytest.mark.parametrize("store_kind", ["recorded", "legacy"])
def test_misplaced__a_copied_eval_file_is_named_by_run_and_report(
        capsys: pytest.CaptureFixture[str], request: pytest.FixtureRequest, store_kind: str, tmp_path: Path) -> None:
    grid_file, out, (a, b) = request.getfixturevalue(store_kind)
    shutil.copyfile(out / "eval" / f"{a}.parquet", out / "eval" / f"{b}.parquet")
    before = snapshot(out)
    code, _, err = run_cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(out))
    assert code == 2
    one_error_line(err, f"eval/{b}.parquet", f"holds rows of cell {a}", "--repair")
    assert snapshot(out) == before
    code, _, err = run_cli(capsys, "report", "--run", str(out), "--out", str(tmp_path / "rep"))
    assert code == 0, err
    assert f"eval/{b}.parquet" in err and "--repair" in err
    progress = (tmp_path / "rep" / "progress.md").read_text()
    assert "| toy | 1 | 0 | 1 | 0 | 2 |" in progress, progress  # b is not done until repaired
    store = load_store(out)
    assert set(store.eval["cell_id"]) == {a}


def test_misplaced__a_swapped_pair_of_eval_files_names_both(recorded) -> None:
    _, out, (a, b) = recorded
    ea, eb = out / "eval" / f"{a}.parquet", out / "eval" / f"{b}.parquet"
    tmp = ea.with_suffix(".x")
    ea.rename(tmp)
    eb.rename(ea)
    tmp.rename(eb)
    damage = find_damage(RunStore(out), RunStore(out).integrity())
    assert {d.rel for d in damage} == {f"eval/{a}.parquet", f"eval/{b}.parquet"}


# ------------------------------------------------------- D11: a way forward
@pytest.mark.parametrize("kind", ["eval", "train"])
def test_corrupt_file__of_an_old_store_names_the_repair_command(
        capsys: pytest.CaptureFixture[str], legacy, kind: str) -> None:
    grid_file, out, ids = legacy
    victim = stored_files(out, ids[0])[kind]
    victim.write_bytes(victim.read_bytes()[:40])  # truncated: unreadable
    code, _, err = run_cli(capsys, "run", "--grid-file", str(grid_file), "--out", str(out))
    assert code == 2
    one_error_line(err, f"damaged file {victim.relative_to(out).as_posix()}", "corrupt Parquet",
                    "rerun `bench run` (same grid and --out) with --repair")
    code, _, err = run_cli(capsys, "report", "--run", str(out), "--out", str(out.parent / "rep"))
    assert code == 0, err
    warnings = [ln for ln in err.splitlines() if ln.startswith("bench: warning:")]
    assert len(warnings) == 1 and "--repair" in warnings[0] and "to complete it" not in err, err


# ------------------------------------------------------ D8: manifest schema
@pytest.mark.parametrize(("runs", "message"), [
    (5, "runs: Input should be a valid list"),
    ("notalist", "runs: Input should be a valid list"),
    ([{"workers": "two"}], "runs.0.workers: Input should be a valid integer"),
])
def test_manifest__a_field_of_the_wrong_type_is_one_line_and_nothing_is_written(
        capsys: pytest.CaptureFixture[str], legacy, runs: object, message: str, tmp_path: Path) -> None:
    grid_file, out, _ = legacy
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["runs"] = runs
    (out / "manifest.json").write_text(json.dumps(manifest))
    before = snapshot(out)
    for args in (["run", "--grid-file", str(grid_file), "--out", str(out)],
                 ["report", "--run", str(out), "--out", str(tmp_path / "rep")]):
        code, _, err = run_cli(capsys, *args)
        assert code == 2
        one_error_line(err, "manifest.json", message)
    assert snapshot(out) == before


def test_eval_metadata__of_the_wrong_type_isone_error_line(legacy) -> None:
    _, out, ids = legacy
    path = out / "eval" / f"{ids[0]}.parquet"
    table = pq.read_table(path)
    meta = {**table.schema.metadata, b"attempts": b'"three"'}
    pq.write_table(table.replace_schema_metadata(meta), path)
    with pytest.raises(BenchError, match="attempts: Input should be a valid integer"):
        RunStore(out).eval_meta(ids[0])


def test_checksums_file__that_is_not_ours_isone_error_line(legacy, recorded) -> None:
    _, out, _ = recorded
    (out / CHECKSUMS_FILE).write_text(json.dumps({"format": "x", "files": []}))
    with pytest.raises(BenchError, match="corrupt .*checksums.json.*format"):
        Checksums.load(out, RunStore(out).read_manifest())


# ------------------------------------------- D6: a broken study beside the run
@pytest.mark.parametrize("content", ["{not json", '{"run": 5}'])
def test_report__a_broken_study_beside_the_run_is_a_warning_not_a_crash(
        capsys: pytest.CaptureFixture[str], legacy, tmp_path: Path, content: str) -> None:
    _, out, _ = legacy
    study = out.parent / "studies" / "other"
    study.mkdir(parents=True)
    (study / "trials.parquet").write_bytes(b"")
    (study / "study.json").write_text(content)
    code, _, err = run_cli(capsys, "report", "--run", str(out), "--out", str(tmp_path / "rep"))
    assert code == 0, err
    index = (tmp_path / "rep" / "index.md").read_text()
    assert "study studies/other beside the run was left out" in index and "study.json" in index
