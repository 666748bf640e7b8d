"""Every command the README shows parses as written (options and choices exist)."""
from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
import typer

from bench.cli import app

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def _commands() -> list[list[str]]:
    """`bench ...` invocations inside the README's fenced code blocks (comments dropped)."""
    out = []
    for block in re.findall(r"```bash\n(.*?)```", README, flags=re.S):
        for line in block.splitlines():
            line = line.split("#", 1)[0].strip()
            if re.match(r"^(\.venv/bin/)?bench\b", line):
                out.append(shlex.split(line)[1:])
    return out


COMMANDS = _commands()


def test_readme__shows_the_main_commands():
    shown = {c[0] for c in COMMANDS if c}
    assert {"run", "report", "grids", "tune", "replay", "eval", "perf"} <= shown


@pytest.mark.parametrize("argv", COMMANDS, ids=[" ".join(c) for c in COMMANDS])
def test_readme__command_parses(argv):
    group = typer.main.get_command(app)
    assert argv[0] in group.commands, f"README uses unknown command {argv[0]!r}"
    # Parsing (not invoking) raises on an unknown option, a missing value or a bad choice.
    group.commands[argv[0]].make_context(argv[0], list(argv[1:]))


def test_readme__quick_start_is_two_make_targets_that_exist():
    quick = README.split("## Quick start", 1)[1].split("##", 1)[0]
    block = re.search(r"```bash\n(.*?)```", quick, flags=re.S).group(1)
    lines = [ln.split("#", 1)[0].strip() for ln in block.splitlines() if ln.strip()]
    assert lines == ["make smoke", "make test"]
    makefile = (ROOT / "Makefile").read_text()
    assert re.search(r"^smoke:", makefile, flags=re.M) and re.search(r"^test:", makefile, flags=re.M)
    ci = (ROOT / ".ci" / "run").read_text()
    assert "make test" in ci
