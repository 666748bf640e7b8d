"""maintenance/complete_run_records.py and maintenance/split_superseded_wall.py: the two one-off
repairs of committed run folders, and bench.store.meta_schema.unexplained_parts they answer to."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from bench.store.meta_schema import RECORD_PARTS, unexplained_parts
from bench.store.run_store import RunStore
from bench.store.schema import CELLS_SCHEMA


def _script(name: str):
    path = Path(__file__).resolve().parents[2] / "maintenance" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


records = _script("complete_run_records")
split = _script("split_superseded_wall")


def test_unexplained_parts__a_part_counts_when_held_or_given_a_reason() -> None:
    full = {p: 1 for p in RECORD_PARTS}
    assert unexplained_parts(full) == []
    assert unexplained_parts({**full, "ended": None, "wall_s": None}) == ["ended", "wall_s"]
    assert unexplained_parts({**full, "ended": None, "unrecorded": {"ended": "killed"}}) == []
    assert unexplained_parts({**full, "ended": None, "unrecorded": {"ended": ""}}) == ["ended"]  # no reason


def test_complete__fills_with_sources_explains_the_rest_keeps_what_is_there() -> None:
    rec = {"grid": "convergence", "started": "2026-12-01T18:16:10+00:00", "workers": 7}
    assert records.complete(rec)
    assert rec["git"] == "4849115e8ae2" and "bf756ce" in rec["reconstructed"]["git"]
    assert rec["workers"] == 7 and "workers" not in rec["reconstructed"]  # held parts stay as recorded
    assert rec.get("ended") is None and "19:54:58" in rec["unrecorded"]["ended"]
    assert unexplained_parts({**rec, "command": "x"}) == []
    again = json.loads(json.dumps(rec))
    assert not records.complete(again) and again == rec  # a second pass changes nothing
    other = {"grid": "paper", "started": "2026-12-02T19:01:59+00:00", "ended": "2026-12-02T21:40:00+00:00"}
    records.complete(other)
    assert other["ended"] == "2026-12-02T21:40:00+00:00" and other["cells_done_after"] == 61
    unknown = {"grid": "paper", "started": "2030-01-01T00:00:00+00:00"}
    assert not records.complete(unknown) and unknown == {"grid": "paper", "started": "2030-01-01T00:00:00+00:00"}


def _cells_row(cell_id: str, wall: float) -> dict:
    row = {f.name: None for f in CELLS_SCHEMA}
    return {**row, "cell_id": cell_id, "status": "done", "wall_s": wall, "attempts": 1, "train_episodes_done": 0,
            "n_robots": 4, "seed": 0, "groups": 1, "ref_size": 1, "search_radius": 1, "c_max": 1,
            "safety_filter": True, "episodes": 0, "horizon": 1, "eval_episodes": 1, "schema_version": 2}


def test_split__moves_the_latest_archived_attempt_out_of_wall_s_once(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    (tmp_path / "manifest.json").write_text(json.dumps({"schema_version": 2, "runs": []}))
    store.write_cells([_cells_row("aaa", 100.0), _cells_row("bbb", 50.0)])
    for name, wall in (("aaa-20260101T000000Z", 20.0), ("aaa-20260102T000000Z", 30.0),
                       ("repair-20260103T000000Z", 99.0)):
        (tmp_path / "superseded" / name).mkdir(parents=True)
        (tmp_path / "superseded" / name / "cells_row.json").write_text(json.dumps({"wall_s": wall}))
    assert len(split.split(tmp_path)) == 1
    cells = store.read_cells().set_index("cell_id")
    # the latest archive carried the earlier one's seconds: 30 in all, not 50; repairs are not attempts
    assert (cells.loc["aaa", "wall_s"], cells.loc["aaa", "superseded_wall_s"]) == (70.0, 30.0)
    assert (cells.loc["bbb", "wall_s"], cells.loc["bbb", "superseded_wall_s"]) == (50.0, 0.0)
    assert split.split(tmp_path) == []


def test_split__an_archive_larger_than_the_cell_is_refused(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    (tmp_path / "manifest.json").write_text(json.dumps({"schema_version": 2, "runs": []}))
    store.write_cells([_cells_row("aaa", 10.0)])
    (tmp_path / "superseded" / "aaa-20260101T000000Z").mkdir(parents=True)
    (tmp_path / "superseded" / "aaa-20260101T000000Z" / "cells_row.json").write_text(json.dumps({"wall_s": 20.0}))
    with pytest.raises(Exception, match="not part of its wall_s"):
        split.split(tmp_path)
    assert split.main([str(tmp_path)]) == 2
