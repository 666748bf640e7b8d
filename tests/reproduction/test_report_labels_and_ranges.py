"""Every committed report: its verdict labels match their intervals, no printed interval of a
rate or count leaves its range, its headline intervals print their simulated coverage (at least
93%, else no interval), and its calibration is its own (docs/decisions/0230-0233)."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2] / "reproduction"
REPORTS = [d.name for d in sorted(ROOT.iterdir()) if (d / "report" / "index.md").is_file()]
CLAIMED = [n for n in REPORTS if (ROOT / n / "report" / "claims.csv").is_file()]
COULD_NOT = "could not have decided it"


def region_excluded(lo: float, hi: float, region: str) -> bool:
    """Whether [lo, hi] lies wholly outside the claim's region ("> a", "< b", "in a..b")."""
    if region.startswith(">"):
        return hi <= float(region[1:])
    if region.startswith("<"):
        return lo >= float(region[1:])
    a, b = (float(x) for x in region[3:].split(".."))
    return hi <= a or lo >= b


def spans_both(lo: float, hi: float, region: str) -> bool:
    """Whether [lo, hi] meets both the claim's region and its complement."""
    if region.startswith(">"):
        return lo <= float(region[1:]) < hi
    if region.startswith("<"):
        return lo < float(region[1:]) <= hi
    a, b = (float(x) for x in region[3:].split(".."))
    return (lo <= a < hi) or (lo < b <= hi)


@pytest.mark.parametrize("name", CLAIMED)
def test_could_not_have_decided__only_where_the_interval_spans_both_sides(name: str) -> None:
    checks = pd.read_csv(ROOT / name / "report" / "claims.csv", keep_default_na=False)
    words = checks["verdict_words"].astype(str)
    said = checks[words.str.contains(COULD_NOT)]
    for r in said.itertuples(index=False):
        lo, hi = float(r.ci_lo), float(r.ci_hi)
        assert not region_excluded(lo, hi, r.claim_region), (r.claim, r.configuration, r.execution)
        assert spans_both(lo, hi, r.claim_region), (r.claim, r.configuration, r.execution)
    # and every undecided check with an interval says where it points
    undecided = checks[(checks["verdict"] == "undecided") & (checks["claim_region"] != "")]
    assert undecided["verdict_words"].str.contains("points (?:toward|against) the claim").all()
    md = (ROOT / name / "report" / "claims.md").read_text(encoding="utf-8")
    assert md.count(COULD_NOT) == int(words.str.contains(COULD_NOT).sum()) + 1  # + the legend's one


def test_region_helpers__catch_a_label_on_the_wrong_side() -> None:
    """The audit's case: 74.8% [35.2, 100] against "< 8%" excludes the claim."""
    assert region_excluded(0.352, 1.0, "< 0.08") and not spans_both(0.352, 1.0, "< 0.08")
    assert spans_both(-1.0, 2.0, "> 0") and not region_excluded(-1.0, 2.0, "> 0")
    assert region_excluded(20.0, 30.0, "in 1.9..5.69") and spans_both(4.0, 9.0, "in 1.9..5.69")


PCT_INTERVAL = re.compile(r"\[(?:95% CI )?(-?[\d.]+)%, (-?[\d.]+)%")


@pytest.mark.parametrize("name", REPORTS)
def test_no_printed_interval_of_a_rate_or_count_leaves_its_range(name: str) -> None:
    report = ROOT / name / "report"
    for md in sorted(report.glob("*.md")):
        for lo, hi in PCT_INTERVAL.findall(md.read_text(encoding="utf-8")):
            assert 0.0 <= float(lo) <= float(hi) <= 100.0, (md.name, lo, hi)
    board = pd.read_csv(report / "leaderboard.csv")
    for col in ("success_lo", "success_hi"):
        v = board[col].dropna()
        assert ((v >= 0.0) & (v <= 1.0)).all(), col
    summary = pd.read_csv(report / "summary.csv")
    for col in summary.columns:
        if col.endswith(("_lo", "_hi")) and (col.startswith(("success_rate", "collision_rate", "correction_rate"))):
            v = summary[col].dropna()
            assert ((v >= 0.0) & (v <= 1.0)).all(), col
        if col.startswith("payload") and col.endswith("_lo"):
            assert (summary[col].dropna() >= 0.0).all(), col
    if (report / "claims.csv").is_file():
        checks = pd.read_csv(report / "claims.csv", keep_default_na=False)
        counts = checks[checks["claim"] == "table1_candidates"]
        lows = pd.to_numeric(counts["ci_lo"], errors="coerce").dropna()
        assert (lows >= 0.0).all()
        for text in checks["numbers"]:
            m = re.search(r"mean candidates [\d.e+]+ \[95% CI (-?[\d.e+]+),", text)
            assert m is None or float(m.group(1)) >= 0.0, text


POINT_INTERVAL = re.compile(r"(-?[\d.]+)% \[(?:95% CI )?(-?[\d.]+)%, (-?[\d.]+)%")


@pytest.mark.parametrize("name", REPORTS)
def test_every_printed_interval_holds_the_mean_printed_beside_it(name: str) -> None:
    """docs/decisions/0248: a logit interval is widened to the plain mean where a skewed
    sample put it to one side (tuned-n40 printed 100.0% [99.8%, 99.9%])."""
    report = ROOT / name / "report"
    for md in sorted(report.glob("*.md")):
        for mean, lo, hi in POINT_INTERVAL.findall(md.read_text(encoding="utf-8")):
            assert float(lo) <= float(mean) <= float(hi), (md.name, mean, lo, hi)
    board = pd.read_csv(report / "leaderboard.csv").dropna(subset=["success_lo"])
    assert ((board["success_lo"] <= board["success"]) & (board["success"] <= board["success_hi"])).all()
    summary = pd.read_csv(report / "summary.csv").dropna(subset=["success_rate_lo"])
    assert ((summary["success_rate_lo"] <= summary["success_rate"])
            & (summary["success_rate"] <= summary["success_rate_hi"])).all()


COVERAGE = re.compile(r"\] \(coverage (\d+\.\d)%(, below 93%)?\)")


@pytest.mark.parametrize("name", REPORTS)
def test_headline_intervals__print_their_simulated_coverage(name: str) -> None:
    """Every success interval of the leaderboard (per configuration and across them) prints its
    simulated coverage; a coverage under 93% says so."""
    text = (ROOT / name / "report" / "leaderboard.md").read_text(encoding="utf-8")
    text = text.split("Probability of improvement", 1)[0]  # the headline tables come first
    rows = [line for line in text.splitlines() if line.startswith("| ") and "[" in line and "%]" in line]
    assert rows
    for line in rows:
        found = COVERAGE.findall(line)
        assert found, line
        for cov, flag in found:
            assert (float(cov) < 93.0) == bool(flag), line


INTERVAL = re.compile(r"\[-?[\d.]+%?, -?[\d.]+%?(; uninformative)?\]")
TRUSTED = re.compile(r"\] \(coverage (\d+\.\d)%\)")
UNTRUSTED = re.compile(r"\(interval not trusted: simulated coverage (\d+\.\d)% < 93%\)")


def headline_cells(name: str) -> list[str]:
    """The cells of the leaderboard's headline tables (per configuration and across them)
    that hold an interval or say why they print none."""
    text = (ROOT / name / "report" / "leaderboard.md").read_text(encoding="utf-8")
    text = text.split("Probability of improvement", 1)[0]
    rows = [line for line in text.splitlines() if line.startswith("| ") and not line.startswith("| N |")
            and not line.startswith("| execution |")]
    return [c for line in rows for c in line.split(" | ") if INTERVAL.search(c) or "not trusted" in c]


OLD_FLAG = ", below 93%)"  # the label before decision 0233: an interval printed with its low coverage
PENDING = pytest.mark.xfail(strict=True, reason="its leaderboard still prints intervals under 93% coverage: "
                            "reports/tables/leaderboard.py is to print 'interval not trusted' (docs/decisions/0233) "
                            "and the report to be rebuilt")


@pytest.mark.parametrize("name", [pytest.param(n, marks=PENDING) if OLD_FLAG in (
    ROOT / n / "report" / "leaderboard.md").read_text(encoding="utf-8") else n for n in REPORTS])
def test_headline_intervals__reach_93_percent_coverage_or_are_not_printed(name: str) -> None:
    """Every headline interval a leaderboard prints has a simulated coverage of at least 93%
    beside it; a row whose interval would cover less prints no interval, only 'interval not
    trusted' with its coverage (docs/decisions/0233)."""
    cells = headline_cells(name)
    assert cells
    for cell in cells:
        if INTERVAL.search(cell):
            m = TRUSTED.search(cell)
            assert m and float(m.group(1)) >= 93.0, cell
        else:
            m = UNTRUSTED.search(cell)
            assert m and float(m.group(1)) < 93.0, cell


@pytest.mark.parametrize("name", [n for n in REPORTS if (ROOT / n / "report" / "calibration.json").is_file()])
def test_calibration__is_the_runs_own(name: str) -> None:
    meta = json.loads((ROOT / name / "report" / "calibration.json").read_text())["meta"]
    assert meta["run"] == f"reproduction/{name}"


def test_full_calibration__at_three_seeds_per_side() -> None:
    rep = json.loads((ROOT / "full" / "report" / "calibration.json").read_text())
    seeds = {r["seeds"] for r in rep["calibration"] if r["seeds"] not in ("as each", "3")}
    assert seeds and all(set(s.split(" vs ")) == {"3"} for s in seeds)
    assert np.isfinite([c["median"] for c in rep["coverage"]]).all()
