"""Methods are plugins: no module outside ``algorithms/<method>`` names a built-in method
for behaviour (SPEC 3). What a method is (learned or planner, its modes, its safety-filter
default, its payload model, its label and colour) is declared by the method and read
through the registry. The modules below name methods as data or as the paper's own
content, each for the reason given; a new mention anywhere else fails this test, and so
does an entry here that no longer mentions one (the list stays honest).
"""
from __future__ import annotations

import io
import re
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BUILT_INS = {"hierarchical", "decentralized", "ic3net", "pibt"}
SCANNED = ("bench", "reports", "studies", "envs", "algorithms/common", "algorithms/base.py",
           "algorithms/registry.py", "algorithms/testing.py")  # not paper/: the paper's wing names its methods
ALLOWED = {
    "bench/design/grids.py": "the smoke grid names the built-ins CI runs (configuration data)",
    "bench/design/costs.py": "cost rates measured per method (data)",
    "bench/design/cost_calibration.py": "the method old runs stacked, before run records listed stacks (0237)",
    "bench/cli.py": "`bench perf --suite` names of benchmarks of the built-ins' own kernels",
    "bench/perf/methods.py": "benchmarks of the built-in methods' kernels",
    "bench/perf/baselines.py": "benchmarks of the built-in baselines' kernels",
    "bench/perf/cli.py": "times commands that name a built-in method (a misspelled one, PIBT's eval)",
    "bench/perf/peers.py": "benchmarks the built-in decentralized trainer against TorchRL's MAPPO",
    "studies/objective.py": "the paper's study (|R_z| x L of its method) is the default study",
}


def _mentions(path: Path) -> list[int]:
    """Lines of ``path`` holding a string literal that is exactly a built-in method name."""
    lines = []
    for tok in tokenize.generate_tokens(io.StringIO(path.read_text()).readline):
        if tok.type == tokenize.STRING and tok.string.strip("'\"") in BUILT_INS:
            lines.append(tok.start[0])
    return lines


def _scanned() -> list[Path]:
    out = []
    for entry in SCANNED:
        p = ROOT / entry
        out += [p] if p.suffix == ".py" else sorted(p.rglob("*.py"))
    return out


def test_no_module_outside_a_method_names_a_built_in_method_for_behaviour() -> None:
    found = {str(p.relative_to(ROOT)): _mentions(p) for p in _scanned()}
    unexpected = {f: lines for f, lines in found.items() if lines and f not in ALLOWED}
    assert not unexpected, f"built-in method names outside their modules: {unexpected}"


def test_every_allowed_module_still_names_one() -> None:
    stale = [f for f in ALLOWED if not _mentions(ROOT / f)]
    assert not stale, f"drop these from ALLOWED: {stale}"


WING = "paper"
OUTSIDE_THE_WING = ("envs", "algorithms", "bench", "reports", "studies", "scripts")


def _imports_of(path: Path) -> set[str]:
    """Every module ``path`` imports (``import x.y``, ``from x.y import z``), at any depth."""
    import ast

    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module)
    return out


def test_no_module_outside_the_paper_wing_imports_it() -> None:
    """The paper's claims, figures, tables and grids live in its wing (paper/), which
    registers with the harness by entry point; nothing below it imports it (SPEC 1)."""
    found = {}
    for entry in OUTSIDE_THE_WING:
        for path in sorted((ROOT / entry).rglob("*.py")):
            hits = sorted(m for m in _imports_of(path) if m == WING or m.startswith(WING + "."))
            if hits:
                found[str(path.relative_to(ROOT))] = hits
    assert not found, f"modules outside the paper's wing import it: {found}"


def test_the_wing_check_sees_an_import_of_the_wing(tmp_path: Path) -> None:
    planted = tmp_path / "m.py"
    planted.write_text("def f():\n    from paper.claims.claims import Claim\n    return Claim\n")
    assert _imports_of(planted) == {"paper.claims.claims"}


SETTING = re.compile(r"\bPAPER_[A-Z0-9_]+\b")  # the paper's settings: paper/settings.py, every PAPER_*


def _settings_named(path: Path) -> list[int]:
    """Lines of ``path`` whose code (not a comment or string) names one of the paper's settings."""
    lines = []
    for tok in tokenize.generate_tokens(io.StringIO(path.read_text(encoding="utf-8")).readline):
        if tok.type == tokenize.NAME and SETTING.fullmatch(tok.string):
            lines.append(tok.start[0])
    return sorted(set(lines))


def test_the_papers_settings_live_in_its_wing_only() -> None:
    """The paper's settings (team sizes, loss probabilities, budgets, Table I, its map) are
    stated once, in paper/settings.py; no module below the wing defines, imports or uses
    a ``PAPER_*`` setting (the harness's own defaults, e.g. a Cell's budgets, are its own)."""
    found = {}
    for entry in OUTSIDE_THE_WING:
        for path in sorted((ROOT / entry).rglob("*.py")):
            lines = _settings_named(path)
            if lines:
                found[str(path.relative_to(ROOT))] = lines
    assert not found, f"modules outside the paper's wing name its settings: {found}"
    assert _settings_named(ROOT / WING / "settings.py")  # the wing still holds them


def test_the_settings_check_sees_a_setting_in_code_only(tmp_path: Path) -> None:
    planted = tmp_path / "m.py"
    planted.write_text('"""PAPER_N in a docstring."""\n# PAPER_P in a comment\nHORIZON = PAPER_HORIZON\n'
                       "from x import PAPER_MAP as M\n")
    assert _settings_named(planted) == [3, 4]
