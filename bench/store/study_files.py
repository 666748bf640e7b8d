"""The files of one study folder ``studies/<name>/`` (``bench tune``), by name.

``studies`` writes them (studies/export.py: the trials, importances and study.json;
studies/report.py: the study's report); the run report (reports/build.py) reads
study.json to find the studies launched for a run and copies their built report files,
so both sides take the names from here.

May import: nothing of the project.
"""
from __future__ import annotations

__all__ = ["CONFIG_FILE", "IMPORTANCES_FILE", "LINK_KEY", "REPORT_DIR", "REPORT_FIGURES", "REPORT_PAGES",
           "TRIALS_FILE", "report_files"]

TRIALS_FILE = "trials.parquet"
IMPORTANCES_FILE = "importances.json"
CONFIG_FILE = "study.json"
LINK_KEY = "run"  # study.json: the run folder name the study was launched for
REPORT_DIR = "report"  # studies/<name>/report/: the study's figures and pages
REPORT_FIGURES = ("study_history", "study_landscape", "study_curves", "study_importances")  # each .png + .pdf
REPORT_PAGES = ("study.md", "study.html")


def report_files() -> list[str]:
    """Names of a built study report under ``REPORT_DIR``, in the order it writes them."""
    return [f"{stem}.{fmt}" for stem in REPORT_FIGURES for fmt in ("png", "pdf")] + list(REPORT_PAGES)
