"""One Parquet reader: the run's rows are read by ``bench.store.run_store`` alone.

``read_table`` reads one file of ours (schema version, added columns, page checksums) and
``RunStore.read_rows`` every file of a dataset (train/, eval/, matrix/: damaged, misplaced
and linked files refused or skipped); the report, the runner, the matrix and the export all
go through them. A second reader (``pq.read_table``, ``pd.read_parquet``, a dataset or a
``concat_tables`` of read files) elsewhere in bench/ or reports/ could read a file the
store would refuse.
"""
from __future__ import annotations

import re
from pathlib import Path

from tests.source_scan import code_matches

ROOT = Path(__file__).resolve().parents[3]
FOLDERS = ("bench", "reports")
READS = re.compile(r"\b(pq\.read_table|read_parquet|ParquetDataset|pq\.ParquetFile|concat_tables)\(")
# the reader itself, and integrity's page-checksum verification (it reads every page of a
# file to verify it and keeps no row)
ALLOWED = {"bench/store/run_store.py", "bench/store/integrity.py"}


def parquet_readers(base: Path, folders: tuple[str, ...]) -> list[str]:
    """'path:line' of every Parquet row read outside ``ALLOWED`` (comments ignored)."""
    return [f"{rel}:{k}" for rel, k, _ in code_matches(base, folders, READS, frozenset(ALLOWED))]


def test_rows_are_read_only_by_the_run_store():
    assert parquet_readers(ROOT, FOLDERS) == []


def test_parquet_readers__finds_a_second_reader(tmp_path):
    (tmp_path / "reports").mkdir()
    (tmp_path / "reports" / "m.py").write_text(
        "import pandas as pd\ndf = pd.read_parquet(path)\n# pq.read_table(p) in a comment\n"
        "t = pa.concat_tables([read_table(p, s) for p in files])\n")
    assert parquet_readers(tmp_path, ("reports",)) == ["reports/m.py:2", "reports/m.py:4"]
