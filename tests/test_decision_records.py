"""docs/decisions/ holds numbered records that the code cites by number; docs/findings/ holds
dated findings linked both ways; docs/decisions.md keeps the heading new entries go under."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RECORDS = sorted((ROOT / "docs" / "decisions").glob("[0-9][0-9][0-9][0-9]-*.md"))
FINDINGS = sorted((ROOT / "docs" / "findings").glob("20[0-9][0-9]-[0-9][0-9]-[0-9][0-9]-*.md"))


def _code_lines() -> list[str]:
    out = subprocess.run(["git", "grep", "-n", "-I", "-E", r"docs/decisions", "--", "*.py", "*.toml", "*.sh",
                          "Makefile", "Dockerfile"], cwd=ROOT, capture_output=True, text=True).stdout
    return out.splitlines()


def test_records__numbered_one_after_another_with_a_decision_each():
    numbers = [int(p.name[:4]) for p in RECORDS]
    assert numbers == list(range(1, len(RECORDS) + 1))
    index = (ROOT / "docs" / "decisions" / "index.md").read_text()
    for p in RECORDS:
        text = p.read_text()
        assert text.startswith(f"# {p.name[:4]}. "), p.name
        assert "\n## Decision\n" in text and "\n## Basis\n" in text, p.name
        assert f"]({p.name})" in index, f"index does not list {p.name}"


STATUS = re.compile(r"^\*Status: (accepted|superseded by \[?(\d{4})\]?[^*]*)\.\*$", re.M)


def test_records__each_has_a_status_accepted_or_superseded_by_an_existing_record():
    """A reader sees whether a record still holds: ``*Status: accepted.*`` or
    ``*Status: superseded by NNNN.*`` (a link may follow the number), under its area line."""
    numbers = {p.name[:4] for p in RECORDS}
    for p in RECORDS:
        found = STATUS.findall(p.read_text())
        assert len(found) == 1, f"{p.name}: needs one line '*Status: accepted.*' or '*Status: superseded by NNNN.*'"
        by = found[0][1]
        assert not by or (by in numbers and by != p.name[:4]), f"{p.name}: superseded by a record that does not exist"


def test_records__the_status_pattern_reads_both_forms():
    assert STATUS.findall("x\n*Status: accepted.*\n") == [("accepted", "")]
    assert STATUS.findall("*Status: superseded by [0007](0007-x.md).*") == [("superseded by [0007](0007-x.md)", "0007")]
    assert STATUS.findall("*Status: maybe.*") == []


def test_code__cites_decisions_by_number_and_every_number_exists():
    numbers = {p.name[:4] for p in RECORDS}
    for line in _code_lines():
        assert not re.search(r"decisions\.md[,:]? *[\"(]", line), f"cites a section of the old file: {line}"
        for n in re.findall(r"docs/decisions/(\d{4})", line):
            assert n in numbers, f"cites a record that does not exist: {line}"


def test_findings__dated_and_linked_with_the_records_they_support():
    assert FINDINGS
    names = {p.name for p in RECORDS}
    for p in FINDINGS:
        text = p.read_text()
        assert text.startswith(f"# {p.name[:10]}: "), p.name
        linked = re.findall(r"\(\.\./decisions/(\d{4}-[^)]+\.md)\)", text)
        assert linked and set(linked) <= names, p.name
        for record in linked:  # ... and the record links back
            assert f"../findings/{p.name}" in (ROOT / "docs" / "decisions" / record).read_text(), (p.name, record)


def test_decisions_md__keeps_the_heading_new_entries_go_under():
    text = (ROOT / "docs" / "decisions.md").read_text()
    assert "\n## New decisions (to be numbered)\n" in text
