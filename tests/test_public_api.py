"""The public surface: every module below lists its names in ``__all__``, each name exists and is
documented, and ``from M import *`` gives exactly ``__all__`` (CONTRIBUTING.md, "Public API").

A class or function is documented by its own docstring; a constant (no docstring of its own) by
a comment on its assignment or the line above it, or by its name in the module docstring.
"""
from __future__ import annotations

import importlib
import inspect
import re

import pytest

PUBLIC_MODULES = [
    "envs",
    # the Method contract
    "algorithms.base", "algorithms.common.episodes", "algorithms.common.execution",
    "algorithms.registry", "algorithms.testing",
    # the command lines
    "bench.cli", "studies.cli",
    # the store: its writer and readers
    "bench.store.run_store", "bench.store.checkpoints", "bench.store.schema", "bench.store.completeness",
    "reports.data.store", "studies.trial_columns",
]


def _documented_constant(module: object, name: str) -> bool:
    """A comment on ``name``'s assignment line or the line above, or ``name`` in the module docstring."""
    if re.search(rf"\b{re.escape(name)}\b", inspect.getdoc(module) or ""):
        return True
    lines = inspect.getsource(module).splitlines()  # type: ignore[arg-type]
    for k, line in enumerate(lines):
        if re.match(rf"^(\w+\s*,\s*)*{re.escape(name)}\b[\w\s,]*(:[^=]+)?=", line):
            above = lines[k - 1].strip() if k else ""
            if "#" in line or above.startswith("#"):
                return True
    return False


def _undocumented(module_name: str) -> list[str]:
    module = importlib.import_module(module_name)
    missing = []
    for name in module.__all__:
        obj = getattr(module, name)
        if inspect.isclass(obj):
            ok = bool(vars(obj).get("__doc__"))
        elif inspect.isfunction(obj) or inspect.isbuiltin(obj) or callable(obj) and hasattr(obj, "__wrapped__"):
            ok = bool(obj.__doc__)
        else:
            home = importlib.import_module(_home(module, name))
            ok = _documented_constant(home, name)
        if not ok:
            missing.append(name)
    return missing


def _home(module: object, name: str) -> str:
    """The module whose source assigns constant ``name`` (re-exported constants live elsewhere)."""
    src = inspect.getsource(module)  # type: ignore[arg-type]
    if re.search(rf"^(\w+\s*,\s*)*{re.escape(name)}\b[\w\s,]*(:[^=]+)?=", src, re.M):
        return module.__name__  # type: ignore[attr-defined]
    found = re.search(rf"^from ([\w.]+) import[^\n]*\b{re.escape(name)}\b", src, re.M)
    assert found, f"{name}: neither assigned nor imported by name in {module.__name__}"  # type: ignore[attr-defined]
    return found.group(1)


@pytest.mark.parametrize("module_name", PUBLIC_MODULES)
def test_public_module__lists_existing_names_in_all(module_name: str) -> None:
    module = importlib.import_module(module_name)
    assert isinstance(module.__all__, list | tuple) and module.__all__, f"{module_name} has no __all__"
    assert len(set(module.__all__)) == len(module.__all__), f"{module_name}.__all__ repeats a name"
    assert [n for n in module.__all__ if not hasattr(module, n)] == []


@pytest.mark.parametrize("module_name", PUBLIC_MODULES)
def test_public_module__every_listed_name_is_documented(module_name: str) -> None:
    assert _undocumented(module_name) == []


@pytest.mark.parametrize("module_name", PUBLIC_MODULES)
def test_public_module__star_import_gives_exactly_all(module_name: str) -> None:
    namespace: dict[str, object] = {}
    exec(f"from {module_name} import *", namespace)  # noqa: S102 - the import under test
    namespace.pop("__builtins__", None)
    assert sorted(namespace) == sorted(importlib.import_module(module_name).__all__)


def test_documented_constant__needs_a_comment_or_the_module_docstring() -> None:
    """The check itself: a bare constant is not documented, a commented one is."""
    import types

    mod = types.ModuleType("fake_public")
    mod.__doc__ = "Holds MENTIONED."
    src = "BARE = 1\nCOMMENTED = 2  # why\n# above\nABOVE = 3\nMENTIONED = 4\n"
    original = inspect.getsource
    inspect.getsource = lambda obj: src if obj is mod else original(obj)  # type: ignore[assignment]
    try:
        assert [n for n in ("BARE", "COMMENTED", "ABOVE", "MENTIONED") if not _documented_constant(mod, n)] == ["BARE"]
    finally:
        inspect.getsource = original
