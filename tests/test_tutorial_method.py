"""The tutorial (docs/guide/tutorial.md) as a new user follows it: the python blocks of steps
1-6, pasted literally into ``mypkg/tutorial.py``, give a method that passes the contract
suite with the test class of step 8, unchanged. A tutorial edit that breaks the method, or
a contract change the tutorial does not follow, fails here."""
from __future__ import annotations

import re
import sys
import types
from pathlib import Path

from algorithms.testing import MethodContract

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "guide" / "tutorial.md"
FENCE = re.compile(r"^```python\n(.*?)^```", flags=re.S | re.M)


def step_blocks(first: int, last: int) -> list[str]:
    """The python blocks of the page's steps ``first``..``last`` (headings "## K. ...")."""
    text = PAGE.read_text(encoding="utf-8")
    parts = re.split(r"^## (\d+)\. ", text, flags=re.M)
    out: list[str] = []
    for number, body in zip(parts[1::2], parts[2::2], strict=True):
        if first <= int(number) <= last:
            out += FENCE.findall(body)
    return out


def _paste_method() -> types.ModuleType:
    """``mypkg.tutorial``: the method file a reader gets by pasting steps 1-6 in order."""
    package = types.ModuleType("mypkg")
    package.__path__ = []
    module = types.ModuleType("mypkg.tutorial")
    module.__file__ = str(PAGE)
    sys.modules["mypkg"], sys.modules["mypkg.tutorial"] = package, module
    package.tutorial = module  # type: ignore[attr-defined]
    exec(compile("\n\n".join(step_blocks(1, 6)), str(PAGE), "exec"), module.__dict__)  # noqa: S102
    return module


_paste_method()
_contract: dict[str, object] = {}
exec(compile("\n".join(step_blocks(8, 8)), f"{PAGE} step 8", "exec"), _contract)  # noqa: S102
TestTutorial = _contract["TestTutorial"]  # the page's own test class, collected here
assert isinstance(TestTutorial, type) and issubclass(TestTutorial, MethodContract)


def test_the_tutorial_method_is_what_step_8_tests() -> None:
    assert TestTutorial.method == "mypkg.tutorial:TutorialMethod"
    assert sys.modules["mypkg.tutorial"].TutorialMethod.learned
