"""Every code block a reader can paste from the README, CONTRIBUTING or a docs page is run or
parsed here, so a snippet that fails when pasted fails CI:

* ``bash`` (and unlabelled) blocks: every ``bench`` command parses with the CLI as written
  (options, values and choices exist), also inside ``docker run IMAGE ...``; every
  ``make`` target exists; every script and grid file a command names exists;
* ``python`` blocks: they parse, every name a block uses is defined by it, by an earlier
  block of the same page or by Python (the pasted TorchRL/SB3 follow-ups once used an
  undefined ``seed``), and blocks that need no third-party RL library (TorchRL, SB3,
  SuperSuit: tests/interop runs those recipes) are executed in order;
* ``toml`` and ``yaml`` blocks parse, and a grid (a block with ``base`` or ``axes``) loads
  with ``bench.design.grid_files.load_grid_file``.
"""
from __future__ import annotations

import builtins
import re
import shlex
import symtable
from pathlib import Path

import pytest
import tomllib
import typer
import yaml

from bench.cli import app

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted([ROOT / "README.md", ROOT / "CONTRIBUTING.md",
                *(p for p in (ROOT / "docs").rglob("*.md") if "data" not in p.relative_to(ROOT / "docs").parts)])
FENCE = re.compile(r"^```([\w+-]*)[^\n]*\n(.*?)^```", flags=re.S | re.M)
HEAVY = ("torchrl", "tensordict", "stable_baselines3", "supersuit")  # run by tests/interop
BENCH = re.compile(r"^(?:nice(?: -n \d+)? )?(?:\.venv/bin/)?bench\b")


def blocks(page: Path) -> list[tuple[str, str]]:
    """(language, code) of every fenced block of ``page``, in order."""
    return [(m.group(1).lower(), m.group(2)) for m in FENCE.finditer(page.read_text(encoding="utf-8"))]


def _id(page: Path) -> str:
    return str(page.relative_to(ROOT))


def shell_lines(code: str) -> list[str]:
    """Commands of a shell block: comments dropped, continuation lines joined."""
    out = []
    for line in code.replace("\\\n", " ").splitlines():
        line = re.sub(r"(^|\s)#.*$", "", line).strip()
        if line:
            out.append(line)
    return out


def written_files(code: str) -> set[str]:
    """Files a shell block's commands write by redirection (``... > tuned.toml``)."""
    return set(re.findall(r"(?<![<>&])>\s*([\w./-]+)", code))


def bench_argv(line: str) -> list[str] | None:
    """The bench arguments of a shell line: ``bench ARGS`` or ``docker run ... IMAGE ARGS``
    (a redirection or pipe ends the arguments)."""
    line = re.split(r"\s(?:[12]?>|\||&&|;)", line, maxsplit=1)[0]
    if BENCH.match(line):
        words = shlex.split(line)
        return words[words.index(next(w for w in words if w.endswith("bench"))) + 1:]
    words = shlex.split(line)
    if words[:2] == ["docker", "run"] and "--entrypoint" not in words and "warehouse-marl-bench" in words:
        rest = words[words.index("warehouse-marl-bench") + 1:]
        return rest or None  # no arguments: the image's default command (the smoke grid)
    return None


SHELL = [(p, code) for p in PAGES for lang, code in blocks(p) if lang in ("bash", "sh", "")]
BENCH_LINES = [(p, argv) for p, code in SHELL for line in shell_lines(code)
               if (argv := bench_argv(line)) is not None]


def test_docs__show_every_bench_command():
    shown = {argv[0] for _, argv in BENCH_LINES if argv}
    group = typer.main.get_command(app)
    assert set(group.commands) <= shown, f"commands no page shows: {set(group.commands) - shown}"


@pytest.mark.parametrize("page,argv", BENCH_LINES, ids=[f"{_id(p)}: {' '.join(a)}" for p, a in BENCH_LINES])
def test_docs__bench_command_parses(page, argv):
    group = typer.main.get_command(app)
    assert argv and argv[0] in group.commands, f"{_id(page)} uses unknown command {argv[:1]}"
    # Parsing (not invoking) raises on an unknown option, a missing value or a bad choice.
    group.commands[argv[0]].make_context(argv[0], list(argv[1:]))
    written = set().union(*(written_files(code) for p, code in SHELL if p == page))
    if "--grid-file" in argv:
        path = argv[argv.index("--grid-file") + 1]
        assert (ROOT / path).is_file() or path in written, f"{_id(page)}: no grid file {path}"


@pytest.mark.parametrize("page", sorted({p for p, _ in SHELL}), ids=_id)
def test_docs__make_targets_and_scripts_exist(page):
    makefile = (ROOT / "Makefile").read_text()
    for code in (c for p, c in SHELL if p == page):
        for line in shell_lines(code):
            words = shlex.split(line)
            if words[0] == "make":
                for target in words[1:]:
                    assert re.search(rf"^{re.escape(target)}:", makefile, flags=re.M), \
                        f"{_id(page)}: no make target {target!r}"
            for word in words:
                if word.startswith("scripts/") or word.startswith("tests/"):
                    assert (ROOT / word).exists(), f"{_id(page)}: {line!r} names a missing {word}"


def undefined_names(code: str, known: set[str]) -> set[str]:
    """Global names ``code`` reads that neither it, ``known`` nor builtins define."""
    top = symtable.symtable(code, "<block>", "exec")
    defined = {s.get_name() for s in top.get_symbols() if s.is_assigned() or s.is_imported()}
    used: set[str] = set()
    tables = [top]
    while tables:
        t = tables.pop()
        tables.extend(t.get_children())
        used |= {s.get_name() for s in t.get_symbols() if s.is_referenced() and s.is_global()
                 or (t is top and s.is_referenced())}
    return used - defined - known - set(dir(builtins))


PY_PAGES = [p for p in PAGES if any(lang == "python" for lang, _ in blocks(p))]


@pytest.mark.parametrize("page", PY_PAGES, ids=_id)
def test_docs__python_blocks_run_or_use_only_names_they_define(page, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a block that writes files writes them here
    known: set[str] = set()
    namespace: dict[str, object] = {"__name__": "__docs__"}
    skipped: set[str] = set()  # names defined by blocks that are only parsed
    for i, (lang, code) in enumerate(blocks(page)):
        if lang != "python":
            continue
        where = f"{_id(page)}, python block {i + 1}"
        compile(code, where, "exec")  # a SyntaxError names the block
        missing = undefined_names(code, known)
        assert not missing, f"{where} uses undefined names {sorted(missing)} (NameError when pasted)"
        top = symtable.symtable(code, "<block>", "exec")
        names = {s.get_name() for s in top.get_symbols() if s.is_assigned() or s.is_imported()}
        reads = undefined_names(code, set()) | {s.get_name() for s in top.get_symbols() if s.is_referenced()}
        heavy = re.search(rf"^\s*(?:from|import) ({'|'.join(HEAVY)})\b", code, flags=re.M)
        if heavy or reads & skipped:  # needs a library tests/interop covers: parsed and checked only
            skipped |= names
        else:
            exec(compile(code, where, "exec"), namespace)  # noqa: S102 - the page's own snippet
        known |= names


def _data_blocks() -> list[tuple[Path, str, str]]:
    return [(p, lang, code) for p in PAGES for lang, code in blocks(p) if lang in ("toml", "yaml", "yml")]


@pytest.mark.parametrize("page,lang,code", _data_blocks(),
                         ids=[f"{_id(p)}: {lang} {i}" for i, (p, lang, _) in enumerate(_data_blocks())])
def test_docs__toml_and_yaml_blocks_parse_and_grids_load(page, lang, code, tmp_path):
    from bench.design.grid_files import load_grid_file

    data = tomllib.loads(code) if lang == "toml" else yaml.safe_load(code)
    assert isinstance(data, dict), f"{_id(page)}: a {lang} block that is not a table"
    if "base" in data or "axes" in data:
        path = tmp_path / f"{data.get('name', 'grid')}.{lang}"
        path.write_text(code)
        grid = load_grid_file(path)
        assert len(grid.cells) >= 1
