"""scripts/stage_run_state.py: what a committed long run keeps in git."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pandas as pd

_spec = importlib.util.spec_from_file_location(
    "stage_run_state", Path(__file__).resolve().parents[2] / "scripts" / "stage_run_state.py")
stage = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(stage)


def test_plan__unfinished_checkpoints_are_added_finished_ones_dropped(tmp_path: Path) -> None:
    run = tmp_path / "paper"
    (run / "checkpoints").mkdir(parents=True)
    (run / "train").mkdir()
    new = "0123456789ab"  # a checkpoint named by its method (checkpoints/<method>-<cell_id>.pt)
    pd.DataFrame({"cell_id": ["aaa", "bbb", "ccc", new], "status": ["done", "running", "pending", "running"]}
                 ).to_parquet(run / "cells.parquet")
    (run / "checkpoints" / f"pibt-{new}.pt").write_bytes(b"x")
    (run / "manifest.json").write_text("{}")
    (run / "checksums.json").write_text("{}")
    for cid in ("aaa", "bbb"):
        (run / "checkpoints" / f"{cid}.pt").write_bytes(b"x")
    tracked = {str(run / "checkpoints" / "aaa.pt"), str(run / "checkpoints" / "bbb.pt"), str(run / "train" / "x")}
    add, drop = stage.plan(run, tracked)
    assert add == [str(run / "cells.parquet"), str(run / "manifest.json"), str(run / "checksums.json"),
                   str(run / "train"), str(run / "checkpoints" / "bbb.pt"),  # no eval/, matrix/, report/; ccc: none
                   str(run / "checkpoints" / f"pibt-{new}.pt")]
    assert drop == [str(run / "checkpoints" / "aaa.pt")]  # done: its checkpoint leaves the index only
    assert (run / "checkpoints" / "aaa.pt").exists()


def test_plan__superseded_rows_are_added_without_their_checkpoints(tmp_path: Path) -> None:
    run = tmp_path / "paper"
    old = run / "superseded" / "aaa-20261202T103152Z"
    (old / "train").mkdir(parents=True)
    pd.DataFrame({"cell_id": ["aaa"], "status": ["running"]}).to_parquet(run / "cells.parquet")
    (run / "manifest.json").write_text("{}")
    for name in ("train/part-000000000.parquet", "eval.parquet", "cells_row.json", "checkpoint.pt"):
        (old / name).write_bytes(b"x")
    add, _ = stage.plan(run, set())
    assert add == [str(run / "cells.parquet"), str(run / "manifest.json"), str(old / "cells_row.json"),
                   str(old / "eval.parquet"), str(old / "train" / "part-000000000.parquet")]


def test_main__refuses_a_run_that_is_still_writing(tmp_path: Path, monkeypatch, capsys) -> None:
    import os
    import sys

    from bench.store.run_store import RunStore

    run = tmp_path / "paper"
    run.mkdir()
    pd.DataFrame({"cell_id": ["aaa"], "status": ["running"]}).to_parquet(run / "cells.parquet")
    (run / "manifest.json").write_text("{}")
    fd = RunStore(run).lock()  # what a live `bench run` holds
    try:
        monkeypatch.setattr(sys, "argv", ["stage_run_state.py", str(run), "--dry-run"])
        assert stage.main() == 2
        assert "still writing" in capsys.readouterr().err
    finally:
        os.close(fd)
