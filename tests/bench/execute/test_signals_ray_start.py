"""A SIGTERM while Ray starts: exit 143 and one line, as after start-up. The
command sends itself SIGTERM from inside the real ``ray.init``, after Ray installed its own
handler and before the node starts (no timing): on 13e50ee Ray's handler answered with
``sys.exit(15)``, no line."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.bench.conftest import REPO, TOY_PATH, toy_spec, write_grid_file

SCRIPT = '''
import os, signal, sys
import ray._private.node as node
from algorithms import registry
registry.register("toy", {toy!r})
from bench.cli import main

def start(self, *a, **k):  # inside ray.init: Ray's own SIGTERM handler is already set
    os.kill(os.getpid(), signal.SIGTERM)
    raise AssertionError("SIGTERM was not handled")

node.Node.__init__ = start
main(["run", "--grid-file", sys.argv[1], "--out", sys.argv[2]])
'''


@pytest.mark.slow
def test_sigterm_inside_the_real_ray_init_is_exit_143_with_one_line(tmp_path: Path) -> None:
    grid = write_grid_file(tmp_path / "g.toml", toy_spec(), {"seed": [0]})
    proc = subprocess.run([sys.executable, "-c", SCRIPT.format(toy=TOY_PATH), str(grid), str(tmp_path / "run")],
                          cwd=REPO, capture_output=True, text=True, timeout=300,
                          env={**os.environ, "RAY_AUTH_MODE": "disabled"})
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 143, proc.stderr[-2000:]
    assert lines == ["bench: error: terminated; checkpoints are kept, rerun the same command to resume"], lines
