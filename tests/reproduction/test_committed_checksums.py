"""Issue 49 item 6: every stored file of every committed run has its recorded SHA-256, and
the bytes match; the stores that predate checksums (and the files of reproduction/full
written before its bench recorded them) say so in ``added_later`` (docs/decisions/0197)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.store.integrity import CHECKSUMS_FILE, find_damage
from bench.store.run_store import RunStore

ROOT = Path(__file__).resolve().parents[2] / "reproduction"
RUNS = [d.name for d in sorted(ROOT.iterdir()) if (d / "cells.parquet").is_file()]


@pytest.mark.parametrize("name", RUNS)
def test_committed_store__every_stored_file_is_recorded_and_matches(name: str) -> None:
    store = RunStore(ROOT / name)
    checks = store.integrity()
    assert checks.active and not checks.missing
    stored = {p.relative_to(store.root).as_posix() for p in store.bench_files()} - {"manifest.json", CHECKSUMS_FILE}
    assert stored and stored <= set(checks.files), sorted(stored - set(checks.files))[:5]
    assert all(f"eval/{cid}.parquet" in checks.files for cid in store.read_cells().query("status == 'done'").cell_id)
    assert find_damage(store, checks) == []


@pytest.mark.parametrize("name", ["paper", "ablation"])
def test_pre_checksum_stores__say_their_digests_were_added_later(name: str) -> None:
    data = json.loads((ROOT / name / CHECKSUMS_FILE).read_text())
    later = data["added_later"]
    assert set(later["files"]) == set(data["files"]) and "not by the bench that wrote them" in later["note"]


def test_full_store__marks_exactly_the_files_its_bench_did_not_record() -> None:
    data = json.loads((ROOT / "full" / CHECKSUMS_FILE).read_text())
    later = set(data["added_later"]["files"])
    assert later < set(data["files"]) and "cells.parquet" not in later
