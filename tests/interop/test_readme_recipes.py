"""The README's interop recipes are the files the interop tests run, character for character."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("name", ["recipe_torchrl.py", "recipe_sb3.py"])
def test_readme__shows_the_interop_recipe_verbatim(name):
    readme = (ROOT / "README.md").read_text()
    section = readme.split("## The environment from other code", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    assert (ROOT / "tests" / "interop" / name).read_text() in blocks
