"""Every file of this repository that the README, CONTRIBUTING, a docs page or a decision
record names by its path (``bench/execute/runner.py``, ``tests/paper/claims/test_claims.py``)
exists, so a reader who opens it finds it. Findings (docs/findings/) are dated records of
what was true then and may name files that have since moved; they are not checked."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted([ROOT / "README.md", ROOT / "CONTRIBUTING.md",
                *(p for p in (ROOT / "docs").rglob("*.md") if "findings" not in p.parts)])
PATH = re.compile(r"(?<![\w./-])((?:bench|reports|paper|algorithms|envs|studies|scripts|maintenance|tests|examples)"
                  r"/[\w/.-]+?\.(?:py|json|toml|sh|map))\b")


def test_named_paths__exist() -> None:
    missing = sorted({f"{page.relative_to(ROOT)}: {m}" for page in PAGES
                      for m in PATH.findall(page.read_text(encoding="utf-8")) if not (ROOT / m).exists()})
    assert not missing, "files named in the docs that do not exist:\n" + "\n".join(missing)


def test_named_paths__the_pattern_finds_what_it_should() -> None:
    text = "see `bench/execute/runner.py` and tests/paper/claims/test_claims.py, not x/bench/a.py"
    assert PATH.findall(text) == ["bench/execute/runner.py", "tests/paper/claims/test_claims.py"]
