"""`--help` shows a boolean option as a flag (`--fresh`), never with a value (`--fresh <bool>`
read as if `bench run --fresh true` worked; it fails: flags take no value)."""
from __future__ import annotations

import re

import pytest
import typer
from typer.testing import CliRunner

from bench.cli import app

COMMANDS = sorted(typer.main.get_command(app).commands)


@pytest.mark.parametrize("command", COMMANDS)
def test_help__boolean_options_read_as_flags(command):
    out = CliRunner().invoke(app, [command, "--help"], terminal_width=100).output
    assert "Usage: bench" in out or "Usage:" in out
    assert "<bool>" not in out, out
    group = typer.main.get_command(app)
    for param in group.commands[command].params:
        if getattr(param, "is_flag", False) and not param.hidden:
            for opt in param.opts:  # the flag's line shows no value after its names
                line = next(ln for ln in out.splitlines() if re.search(rf"(^|\s|, ){re.escape(opt)}\b", ln))
                assert not re.search(rf"{re.escape(opt)}\s+<", line), line


def test_help__root_options_read_as_flags():
    out = CliRunner().invoke(app, ["--help"], terminal_width=100).output
    assert "--version" in out and "<bool>" not in out
