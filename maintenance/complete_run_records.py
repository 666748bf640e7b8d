"""Complete the manifest records of the committed runs whose bench wrote no end record
(records of 2026-11-30 and 2026-12-01, before 63b35b4 added commit, machine, end and wall time)
or whose run was stopped before writing it (docs/results-schema.md, manifest.json).

Each part is filled from the run's own data or its git history, and named in the record's
``reconstructed`` with its source; a part the data cannot give is named in ``unrecorded``
with the reason and, where they exist, its bounds. A record is matched by (grid, started), so
the copies that maintenance/import_cells.py made in another run folder are completed too. Parts a
record already holds are never changed; a second run changes nothing.

    .venv/bin/python maintenance/complete_run_records.py reproduction/paper reproduction/ablation reproduction/full

Imports: bench.store only.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from bench.store.run_store import RunStore
from envs.errors import BenchError

# The machine the paper run of 2026-12-01T19:58:26 recorded. The convergence run of 18:16 and
# the ablation run of 18:19 were staged together from one working tree (commit bf756ce), and
# the ablation run went on, one process, until the SIGTERM of 20:40 that also stopped that
# paper run (commit f073788): the three ran on one machine.
_MACHINE_2026_12_01 = {"arch": "x86_64", "cpu": "Intel(R) Xeon(R) Processor", "cpus": 2, "host": "vm",
                       "os": "Linux-6.18.44-fc-v657-x86_64-with-glibc2.36"}
_SAME_MACHINE = ("the machine of the paper run started 2026-12-01T19:58:26: one working tree staged this run "
                 "beside it (commits bf756ce, f073788) and the ablation run, one process from 18:19 until the "
                 "SIGTERM of 20:40 that also stopped that paper run, spans both")
_OLD_BENCH = "the bench of this run wrote no end record (end records since 63b35b4, 2026-12-01T18:27)"

# (grid, started) -> part -> (value, source) or (None, why there is none)
RECORDS: dict[tuple[str, str], dict[str, tuple[Any, str]]] = {
    ("convergence", "2026-11-30T07:33:16+00:00"): {
        "git": ("e13bbbe3fd62", "the manifest's git_sha written when this run started (commit 7daebd6); "
                                "the N = 20 cells' versions_json name it too"),
        "workers": (2, "its command (--workers 2)"),
        "cells_done_before": (0, "the run folder's first invocation (manifest created at its start)"),
        "cells_done_in_run": (6, "the six N = 20 eval files of commits 7daebd6 and 4849115, the state the "
                                 "next invocation resumed from"),
        "cells_done_after": (6, "as cells_done_in_run"),
        "ended": (None, f"{_OLD_BENCH}; it was still running at 2026-11-30T08:52 (commit 4849115 staged it "
                        "part-way) and nothing it did later was kept"),
        "wall_s": (None, "no end (see ended); its cells' own worker seconds are in cells.parquet"),
        "machine": (None, "not recorded by the bench of e13bbbe (machine records since 63b35b4)"),
    },
    ("convergence", "2026-12-01T18:16:10+00:00"): {
        "git": ("4849115e8ae2", "the manifest's git_sha written when this run started (commit bf756ce); "
                                "the N = 40 cells' versions_json name it too"),
        "workers": (1, "its command (--workers 1)"),
        "cells_done_before": (6, "the six eval files of commit 4849115, the state it resumed"),
        "cells_done_in_run": (6, "twelve eval files when its cells moved to reproduction/paper (commit d1660a5)"),
        "cells_done_after": (12, "as cells_done_in_run"),
        "machine": (_MACHINE_2026_12_01, _SAME_MACHINE),
        "ended": (None, f"{_OLD_BENCH}; it ended between 2026-12-01T19:54:58 (its start plus the 5,927.6 "
                        "worker-seconds its one worker spent on the six cells it finished: their wall_s less "
                        "what commit 4849115's checkpoints held) and 19:58:26 (the paper run started on its "
                        "cells, moved by commit d1660a5)"),
        "wall_s": (None, "no end record; between 5,928 and 6,136 s (see ended)"),
    },
    ("paper", "2026-12-02T19:01:59+00:00"): {
        "ended": ("2026-12-02T21:37:00+00:00", "commit c3206ad's message (bench run on dd87a9e, "
                  "2026-12-02 19:02-21:37 UTC), to the minute: the run was stopped without writing its end"),
        "wall_s": (9301.0, "ended less started, to the minute"),
        "cells_done_after": (61, "the next invocation's cells_done_before; no invocation in between "
                                 "(each writes its record when it starts)"),
        "cells_done_in_run": (16, "cells_done_after less cells_done_before"),
    },
    ("full", "2026-12-03T16:52:20+00:00"): {
        **{part: (None, "an import of finished cells by scripts/import_cells.py (cells_imported), not a training "
                        "invocation: the records with imported_from trained them")
           for part in ("command", "git", "machine", "workers", "wall_s", "cells_done_in_run")},
        "cells_done_before": (0, "the run folder's first record of its own"),
        "cells_done_after": (84, "cells_imported"),
    },
    ("full", "2026-12-04T21:11:11+00:00"): {
        "cells_done_in_run": (6, "cells.parquet as the run left it (commit e6ca913): hierarchical N = 80, p = 0.6 and "
                                 "N = 90, p = 0.4, seeds 0-2, done in this part"),
        "cells_done_after": (99, "cells.parquet as the run left it (commit e6ca913)"),
        "ended": (None, "the session that ran it was cut off and its process ended with it, before the bench wrote "
                        "its end; its training rows (per-episode wall_s of the three seed stacks it trained: 613 + "
                        "1,188 + 585 s) put the end after about 21:53 UTC"),
        "wall_s": (None, "no end (see ended); at least 2,386 s of training by the same rows"),
    },
    ("ablation", "2026-12-01T18:19:45+00:00"): {
        "git": ("40869b65cf2f-dirty", "the manifest's git_sha written when this run started (commit bf756ce)"),
        "workers": (1, "its command (--workers 1)"),
        "cells_done_before": (0, "the run folder's first invocation (manifest created at its start)"),
        "cells_done_in_run": (9, "the nine eval files of commit f073788; the next invocation's cells_done_before"),
        "cells_done_after": (9, "as cells_done_in_run"),
        "ended": ("2026-12-01T20:40:00+00:00", "commit f073788's message (run 18:19-20:40, stopped with "
                  "SIGTERM), to the minute; " + _OLD_BENCH),
        "wall_s": (8415.0, "ended less started, to the minute"),
        "machine": (_MACHINE_2026_12_01, _SAME_MACHINE),
    },
}


def complete(record: dict[str, Any]) -> bool:
    """Fill ``record`` in place from RECORDS; True if it changed."""
    parts = RECORDS.get((str(record.get("grid")), str(record.get("started"))), {})
    changed = False
    for part, (value, why) in parts.items():
        if record.get(part) is not None:
            continue
        key = "unrecorded" if value is None else "reconstructed"
        if value is not None:
            record[part] = value
        if record.setdefault(key, {}).get(part) != why:
            record[key][part] = why
            changed = True
    return changed


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", type=Path, help="run folders with a manifest.json")
    args = ap.parse_args(argv)
    try:
        for root in args.runs:
            store = RunStore(root)
            manifest = store.read_manifest()
            if manifest is None:
                raise BenchError(f"{root}: no manifest.json")
            n = sum(complete(r) for r in manifest.get("runs", []))
            if n:
                store.write_manifest(manifest)
            print(f"{root}: {n} record(s) completed")
    except BenchError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
