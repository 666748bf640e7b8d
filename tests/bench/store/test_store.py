"""The store: atomic writes, schema round trip, version and corruption checks, resume pieces."""
from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import torch

from bench.store.checkpoints import checkpoint_cell, checkpoint_name, load_checkpoint
from bench.store.run_store import RunStore, read_table
from bench.store.schema import (
    CELLS_SCHEMA,
    EVAL_SCHEMA,
    SCHEMA_VERSION,
    TRAIN_SCHEMA,
    rows_to_table,
)
from envs.atomic import atomic_file
from envs.errors import BenchError

CID = "0123456789ab"  # a cell id: 12 hex digits


def _metric_row(episode: int, **extra: float) -> dict:
    return {"episode": episode, "team_return": 1.5 * episode, "success_rate": 0.25, "collision_rate": 0.0,
            "invalid_rate": 0.1, "correction_rate": 0.0, "mean_candidates": float("nan"),
            "fallback_rate": float("nan"), "predictor_error": float("nan"),
            "payload_scalars_per_step": 36.0, "payload_dec_per_step": 1140.0, "steps": 500,
            "execution": "argmax", "scenario": f"{episode:016x}", **extra}


def test_atomic_file__failure_mid_write_keeps_the_old_file_and_no_temp(tmp_path: Path) -> None:
    target = tmp_path / "x.bin"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError), atomic_file(target) as fh:
        fh.write(b"half of the new")
        raise RuntimeError("crash")
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.bin"]
    with atomic_file(target) as fh:
        fh.write(b"new")
    assert target.read_bytes() == b"new"


def test_train_rows__round_trip_with_nan_for_missing_losses_and_extra_keys_dropped(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    rows = [_metric_row(e, actor_loss=0.5, wall_s=0.01, entropy=3.0) for e in range(4)]
    store.write_train_part(CID, 0, rows[:2])
    store.write_train_part(CID, 2, rows[2:])
    df = store.read_train()
    assert list(df.columns) == TRAIN_SCHEMA.names
    assert df["episode"].tolist() == [0, 1, 2, 3] and (df["cell_id"] == CID).all()
    assert df["actor_loss"].tolist() == [0.5] * 4
    assert df["critic_loss"].isna().all() and df["predictor_loss"].isna().all()
    assert df["steps"].dtype == "int64"
    # pandas reads the dataset directory directly, too
    assert len(pd.read_parquet(tmp_path / "train")) == 4


def test_eval_rows__round_trip_and_metadata(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    store.write_eval(CID, [_metric_row(e) for e in range(3)], {"wall_s": 2.5, "attempts": 2})
    df = store.read_eval()
    assert list(df.columns) == EVAL_SCHEMA.names and df["team_return"].tolist() == [0.0, 1.5, 3.0]
    assert store.eval_meta(CID) == {"wall_s": 2.5, "attempts": 2}
    assert store.eval_meta("zzz") is None


def test_cells_table__round_trip_keeps_types(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    row = {f.name: None for f in CELLS_SCHEMA}
    row.update(cell_id="c1", grid="g", method="pibt", n_robots=8, loss_p=0.2, seed=0, groups=4, ref_size=8,
               search_radius=2, c_max=500, safety_filter=False, layout="tiny", episodes=0, horizon=10,
               eval_episodes=5, on_goal="remove", loss_model="bernoulli", executions="planner",
               params_json="{}", config_json="{}",
               status="done", error="", train_episodes_done=0, wall_s=1.0, superseded_wall_s=0.5, peak_mem_mb=400.0,
               attempts=1, versions_json="{}", schema_version=SCHEMA_VERSION)
    store.write_cells([row])
    df = store.read_cells()
    assert df.to_dict("records") == [row]


def test_cells_table__superseded_wall_s_absent_or_missing_reads_as_zero(tmp_path: Path) -> None:
    """superseded_wall_s came within schema version 2: a cells.parquet without the column, or a
    row written without it, has no discarded attempt recorded (0, not NaN: plan adds to it)."""
    store = RunStore(tmp_path)
    row = {f.name: None for f in CELLS_SCHEMA} | dict(
        cell_id="c1", n_robots=8, seed=0, groups=4, ref_size=8, search_radius=2, c_max=500, safety_filter=False,
        episodes=0, horizon=10, eval_episodes=5, train_episodes_done=0, attempts=1, schema_version=SCHEMA_VERSION)
    store.write_cells([row])
    assert store.read_cells()["superseded_wall_s"].tolist() == [0.0]
    table = pq.read_table(store.cells_path)
    pq.write_table(table.drop_columns(["superseded_wall_s"]), store.cells_path)
    assert store.read_cells()["superseded_wall_s"].tolist() == [0.0]
    assert pq.read_schema(store.cells_path).metadata[b"schema_version"] == str(SCHEMA_VERSION).encode()


@pytest.mark.parametrize("column", ["steps", "execution"])
def test_rows_to_table__missing_required_column_is_an_error(column: str) -> None:
    with pytest.raises(KeyError, match=column):
        rows_to_table([{k: v for k, v in _metric_row(0).items() if k != column} | {"cell_id": "a"}], EVAL_SCHEMA)


def test_read__other_schema_version_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "old.parquet"
    table = rows_to_table([_metric_row(0) | {"cell_id": "a"}], EVAL_SCHEMA)
    pq.write_table(table.replace_schema_metadata({b"schema_version": b"0"}), path)
    with pytest.raises(BenchError, match="schema version 0"):
        read_table(path, EVAL_SCHEMA)
    pq.write_table(pa.table({"x": [1]}), path)  # no version at all: not ours
    with pytest.raises(BenchError, match="schema version None"):
        read_table(path, EVAL_SCHEMA)


def test_read__corrupt_parquet_is_a_bench_error_naming_the_file(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    store.write_eval(CID, [_metric_row(0)], {})
    data = store.eval_path(CID).read_bytes()
    store.eval_path(CID).write_bytes(data[: len(data) // 2])
    with pytest.raises(BenchError, match=rf"corrupt Parquet file .*{CID}\.parquet"):
        store.read_eval()
    with pytest.raises(BenchError, match="corrupt"):
        store.eval_meta(CID)


def test_manifest__other_version_is_refused(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    store.write_manifest({"schema_version": SCHEMA_VERSION + 1})
    with pytest.raises(BenchError, match=f"schema version {SCHEMA_VERSION + 1}"):
        store.read_manifest()


def test_discard_parts_from__removes_parts_not_covered_by_the_checkpoint(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    for first in (0, 4, 8):
        store.write_train_part(CID, first, [_metric_row(first + k) for k in range(4)])
    assert store.discard_parts_from(CID, 8) == 1
    assert [f for f, _ in store.train_parts(CID)] == [0, 4]
    assert store.read_train()["episode"].tolist() == list(range(8))


def test_temp_files__are_ignored_by_readers_and_cleaned(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    store.write_train_part(CID, 0, [_metric_row(0)])
    stray = tmp_path / "train" / CID / ".part-000000004.parquet.xyz.tmp"
    stray.write_bytes(b"torn write")
    assert len(pd.read_parquet(tmp_path / "train")) == 1
    assert len(store.read_train()) == 1
    assert store.remove_temp_files() == 1 and not stray.exists()


def test_checkpoint__round_trip_with_weights_only_and_format_check(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    state = {"w": torch.arange(3.0), "iterations": 2, "gen": torch.Generator().get_state()}
    store.write_checkpoint(CID, {"cell": "{}", "episodes_done": 8, "state": state})
    ckpt = store.read_checkpoint(CID)
    assert ckpt["episodes_done"] == 8 and torch.equal(ckpt["state"]["w"], state["w"])
    torch.save({"something": "else"}, tmp_path / "foreign.pt")
    with pytest.raises(BenchError, match="not a bench checkpoint"):
        load_checkpoint(tmp_path / "foreign.pt")
    old = {**torch.load(store.ckpt_path(CID), weights_only=True), "schema_version": 1}
    torch.save(old, tmp_path / "v1.pt")  # schema 2 changed eval rows only: v1 checkpoints load
    assert torch.equal(load_checkpoint(tmp_path / "v1.pt")["state"]["w"], state["w"])
    torch.save({**old, "schema_version": SCHEMA_VERSION + 1}, tmp_path / "vnext.pt")
    with pytest.raises(BenchError, match=f"schema version {SCHEMA_VERSION + 1}"):
        load_checkpoint(tmp_path / "vnext.pt")
    (tmp_path / "torn.pt").write_bytes(store.ckpt_path(CID).read_bytes()[:100])
    with pytest.raises(BenchError, match="corrupt checkpoint"):
        load_checkpoint(tmp_path / "torn.pt")


def test_check_writable__refuses_a_file_as_run_directory(tmp_path: Path) -> None:
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(BenchError, match="not a directory"):
        RunStore(f / "run").check_writable()
    RunStore(tmp_path / "new" / "run").check_writable()  # creatable: fine, and nothing created
    assert not (tmp_path / "new").exists()


def test_manifest__is_json_with_version(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    store.write_manifest({"schema_version": SCHEMA_VERSION, "grid": "smoke"})
    assert json.loads(store.manifest_path.read_text())["grid"] == "smoke"
    assert store.require_run()["grid"] == "smoke"
    with pytest.raises(BenchError, match="not a bench run directory"):
        RunStore(tmp_path / "missing").require_run()


def test_lock__a_second_run_on_the_same_directory_is_refused(tmp_path: Path) -> None:
    import os

    store = RunStore(tmp_path)
    assert RunStore(tmp_path / "missing").lock() is None
    fd = store.lock()
    try:
        with pytest.raises(BenchError, match="another bench run is using"):
            RunStore(tmp_path).lock()
    finally:
        os.close(fd)
    os.close(RunStore(tmp_path).lock())  # free again once released
    assert list(tmp_path.iterdir()) == []  # locking creates no file


@pytest.mark.parametrize(("method", "name"), [
    ("hierarchical", f"hierarchical-{CID}.pt"),
    ("my_pkg.methods:MyMethod", f"mymethod-{CID}.pt"),  # a module:Class method by its class name
    (None, f"{CID}.pt"),  # the name of checkpoints written before names carried the method
])
def test_checkpoint_name__carries_the_method_and_gives_back_the_cell(method, name) -> None:
    assert checkpoint_name(CID, method) == name and checkpoint_cell(name) == CID
    assert checkpoint_cell("best.pt") is None and checkpoint_cell(f"x{CID}.pt") is None


def test_checkpoint__new_ones_are_named_by_method_and_old_names_still_read(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    state = {"w": torch.arange(3.0)}
    store.write_checkpoint(CID, {"cell": "{}", "method": "pibt", "state": state})
    assert [p.name for p in store.ckpt_dir.iterdir()] == [f"pibt-{CID}.pt"]
    assert store.ckpt_path(CID) == store.ckpt_path(CID, "pibt") == store.ckpt_dir / f"pibt-{CID}.pt"
    old_cid = "ba9876543210"  # a committed store's checkpoint: checkpoints/<cell_id>.pt
    torch.save(torch.load(store.ckpt_path(CID), weights_only=True), store.ckpt_dir / f"{old_cid}.pt")
    for method in (None, "pibt"):
        assert torch.equal(store.read_checkpoint(old_cid, method)["state"]["w"], state["w"])
    store.write_checkpoint(old_cid, {"cell": "{}", "method": "pibt", "state": state})  # a resumed old run
    assert sorted(p.name for p in store.ckpt_dir.iterdir()) == [f"{old_cid}.pt", f"pibt-{CID}.pt"]
    assert sorted(p.name for p in store.bench_files()) == [f"{old_cid}.pt", f"pibt-{CID}.pt"]
