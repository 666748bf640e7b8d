"""scripts/record_checksums.py: digests of an older store recorded as added later put its
checksums in force (an edit is then damage); a store with damage is refused, nothing written."""
from __future__ import annotations

import importlib.util
import json
from collections.abc import Iterator
from pathlib import Path

import pytest

from algorithms import registry
from bench.design.grid_files import load_grid_file
from bench.store.integrity import CHECKSUMS_FILE, find_damage
from bench.store.run_store import RunStore
from tests.bench.conftest import toy_spec, write_finished_store, write_grid_file
from tests.bench.toy_method import TOY_PATH

_spec = importlib.util.spec_from_file_location(
    "record_checksums", Path(__file__).resolve().parents[2] / "scripts" / "record_checksums.py")
assert _spec is not None and _spec.loader is not None
_module = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_module)
main = _module.main


@pytest.fixture
def legacy(tmp_path: Path) -> Iterator[Path]:
    """A finished one-cell toy run written without checksums (as an older bench did)."""
    registry.register("toy", TOY_PATH)
    grid = load_grid_file(write_grid_file(tmp_path / "g.toml", toy_spec(), {"seed": [0]}))
    write_finished_store(tmp_path / "run", grid)
    yield tmp_path / "run"
    registry.unregister("toy")


def test_record_checksums__marks_them_added_later_and_puts_them_in_force(legacy: Path) -> None:
    assert main([str(legacy)]) == 0
    data = json.loads((legacy / CHECKSUMS_FILE).read_text())
    assert set(data["added_later"]["files"]) == set(data["files"]) and "cells.parquet" in data["files"]
    victim = next((legacy / "eval").glob("*.parquet"))
    victim.write_bytes(victim.read_bytes()[:-1] + b"\x00")
    damage = find_damage(RunStore(legacy), RunStore(legacy).integrity())
    assert [d.rel for d in damage] == [f"eval/{victim.name}"]
    assert main([str(legacy)]) == 2  # damage: nothing recorded over it
    assert json.loads((legacy / CHECKSUMS_FILE).read_text()) == data
