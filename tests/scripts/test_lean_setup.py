"""The quick start installs what it needs: ``make smoke`` sets up the runtime
only, ``make test`` (and CI's ``make setup``) add the dev extra, and the package metadata
uses the SPDX license form, so setuptools prints no deprecation banner.
A fresh ``make smoke`` venv measured 73 packages, 1.9 GB (README); this checks the recipe."""
from __future__ import annotations

import re
from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parents[2]
MAKEFILE = (ROOT / "Makefile").read_text()
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
DEV_ONLY = ("pytest", "mutmut", "torchrl", "mkdocs", "ruff", "mypy", "hypothesis")


def _name(req: str) -> str:
    return re.split(r"[<>=!~\[ ;]", req, maxsplit=1)[0].lower()


def _prerequisites(target: str) -> list[str]:
    return re.search(rf"^{re.escape(target)}:([^\n]*)$", MAKEFILE, flags=re.M).group(1).split()


def _recipe(target: str) -> str:
    return re.search(rf"^{re.escape(target)}:[^\n]*\n((?:\t[^\n]*\n)+)", MAKEFILE, flags=re.M).group(1)


def test_runtime_dependencies_hold_no_test_lint_or_docs_tool() -> None:
    runtime = {_name(r) for r in PYPROJECT["project"]["dependencies"]}
    dev = {_name(r) for r in PYPROJECT["project"]["optional-dependencies"]["dev"]}
    assert not runtime & {n for n in dev if n.startswith(DEV_ONLY)}
    assert {"pytest", "mutmut", "torchrl", "mkdocs"} <= dev


def test_make_smoke_installs_the_runtime_and_make_test_the_dev_extra() -> None:
    assert _prerequisites("smoke") == ["runtime"]
    assert _prerequisites("runtime") == ["$(VENV)/.installed"]
    assert "EXTRAS" not in _recipe("$(VENV)/.installed")
    assert _prerequisites("test") == ["setup"] and _prerequisites("setup") == ["$(VENV)/.installed-dev"]
    assert "EXTRAS=dev bash scripts/setup.sh" in _recipe("$(VENV)/.installed-dev")
    for target in ("lint", "docs", "example-check"):  # CI's other steps have the dev tools too
        assert _prerequisites(target) == ["setup"], target
    setup_sh = (ROOT / "scripts" / "setup.sh").read_text()
    assert 'EXTRAS="${EXTRAS:-}"' in setup_sh and '-e ".${EXTRAS:+[$EXTRAS]}"' in setup_sh


def test_the_license_is_an_spdx_string_with_a_setuptools_that_reads_it() -> None:
    assert PYPROJECT["project"]["license"] == "MIT"  # the table form is deprecated (a banner per build)
    backend = [r for r in PYPROJECT["build-system"]["requires"] if _name(r) == "setuptools"]
    assert backend == ["setuptools>=77"]
