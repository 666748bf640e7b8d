"""The README is a short introduction: the two quick-start commands, a headline result, links
that resolve, nothing dated and no internal issue numbers (the docs pages hold the rest;
tests/test_docs_snippets.py runs or parses every code block of both)."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def test_readme__quick_start_is_two_make_targets_that_exist():
    quick = README.split("## Quick start", 1)[1].split("##", 1)[0]
    block = re.search(r"```bash\n(.*?)```", quick, flags=re.S).group(1)
    lines = [ln.split("#", 1)[0].strip() for ln in block.splitlines() if ln.strip()]
    assert lines == ["make smoke", "make test"]
    makefile = (ROOT / "Makefile").read_text()
    assert re.search(r"^smoke:", makefile, flags=re.M) and re.search(r"^test:", makefile, flags=re.M)
    ci = (ROOT / ".ci" / "run").read_text()
    assert "make test" in ci


def test_readme__fits_a_newcomers_five_minutes():
    assert len(README.splitlines()) < 200
    for heading in ("## Quick start", "## Headline result", "## Running the paper and full grids",
                    "## Bring your own method", "## Citing", "## Documentation"):
        assert heading in README, heading
    assert "reproduction/full/report/success_vs_n.png" in README  # the top figure, decisions/0143


def test_readme__nothing_dated_and_no_internal_issue_numbers():
    assert not re.search(r"\b20\d\d-\d\d-\d\d\b", README), "a date in the README"
    assert not re.search(r"\bissues? #?\d+", README, flags=re.I), "an internal issue number in the README"
    commits = [h for h in re.findall(r"\b[0-9a-f]{7,40}\b", README)
               if re.search(r"\d", h) and re.search(r"[a-f]", h)]
    assert not commits, f"commit ids in the README: {commits}"


def test_readme__links_to_files_that_exist():
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", README)
    assert targets
    missing = [t for t in targets if "://" not in t and not (ROOT / t).exists()]
    assert not missing, f"README links to missing files: {missing}"
