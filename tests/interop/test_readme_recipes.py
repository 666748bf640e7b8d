"""The interop recipes docs/interop.md shows are the files the interop tests run, character for
character (its follow-up blocks are checked for undefined names by tests/test_docs_snippets.py)."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("name", ["recipe_torchrl.py", "recipe_sb3.py"])
def test_docs__show_the_interop_recipe_verbatim(name):
    page = (ROOT / "docs" / "interop.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", page, flags=re.S)
    assert (ROOT / "tests" / "interop" / name).read_text() in blocks
