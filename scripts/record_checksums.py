"""Record the SHA-256 of every stored file of a committed run that has none yet, marked as
added later (docs/decisions/0197): reproduction/paper and
reproduction/ablation predate checksums, and reproduction/full's imported cells and the
files of its first parts were written before its bench recorded them.

    .venv/bin/python scripts/record_checksums.py reproduction/paper reproduction/full reproduction/ablation

Refuses (exit 2, one line) a run with any damaged or misplaced file: only bytes that pass
every other check (Parquet page checksums, the cell each file names, the digests already
recorded) are vouched for. The committed reports rebuild byte for byte from these bytes
(tests/reproduction), which is what the ``note`` says vouches for them.
"""
from __future__ import annotations

import argparse
import sys
from datetime import datetime, timezone
from pathlib import Path

from bench.store.integrity import CHECKSUMS_FILE, find_damage
from bench.store.run_store import RunStore
from envs.errors import BenchError

NOTE = ("recorded after the files were written, from the bytes committed to git, whose reports "
        "rebuild byte for byte from them (tests/reproduction); not by the bench that wrote them")


def record(run: Path, date: str) -> list[str]:
    """Add the missing digests of ``run``; the paths added."""
    store = RunStore(run)
    store.require_run()
    checks = store.integrity()
    damage = find_damage(store, checks)
    if damage:
        raise BenchError(f"{run}: {damage[0].line()}; nothing recorded")
    files = [p for p in store.bench_files() if p.name not in ("manifest.json", CHECKSUMS_FILE)]
    return checks.add_later(files, date, NOTE)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path)
    args = ap.parse_args(argv)
    date = datetime.now(timezone.utc).date().isoformat()
    try:
        for run in args.runs:
            added = record(run, date)
            print(f"{run}: {len(added)} digests recorded as added later")
    except BenchError as exc:
        print(f"record_checksums: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
