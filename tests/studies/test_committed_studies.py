"""The committed studies (``reproduction/studies/<study>/``): the report in git is the one
today's code builds from the study's own files (``trials.parquet``, ``importances.json``,
``study.json``), byte for byte, so a stale study report or one built by other code cannot
stay committed. A study still running has only its journal and is skipped."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from bench.store.study_files import CONFIG_FILE, IMPORTANCES_FILE, REPORT_DIR, TRIALS_FILE, report_files
from studies.published import STUDIES_ROOT
from studies.report import build_study_report

FINISHED = sorted(p.parent.name for p in STUDIES_ROOT.glob(f"*/{TRIALS_FILE}"))


@pytest.mark.parametrize("study", FINISHED)
def test_committed_study_report__rebuilds_byte_for_byte(study: str, tmp_path: Path) -> None:
    committed = STUDIES_ROOT / study
    for name in (TRIALS_FILE, IMPORTANCES_FILE, CONFIG_FILE):
        shutil.copy(committed / name, tmp_path / name)
    build_study_report(tmp_path)
    for name in report_files():
        rebuilt, stored = tmp_path / REPORT_DIR / name, committed / REPORT_DIR / name
        assert stored.read_bytes() == rebuilt.read_bytes(), f"{stored} is not what today's code builds"
