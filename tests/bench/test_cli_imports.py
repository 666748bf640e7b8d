"""Commands that do not train or simulate do not import torch or Ray: help
and the one-line errors of user mistakes answer in about a second. Each case runs in a fresh
interpreter (an earlier import would hide a later one)."""
from __future__ import annotations

import subprocess
import sys

import pytest

PROBE = """
import sys
from bench.cli import main
try:
    main(sys.argv[1:])
except SystemExit as exc:
    print("EXIT", exc.code)
print("HEAVY", sorted(m for m in ("torch", "ray") if m in sys.modules))
"""


@pytest.mark.parametrize("argv, code", [
    (["--help"], 0),
    (["run", "--help"], 0),
    (["eval", "--method", "pibtt"], 2),  # a misspelled method
    (["run", "--grid", "smoke", "--set", "horizn=32"], 2),  # a misspelled override
    (["run", "--grid", "smoke", "--log", "tensorbored"], 2),
    (["report", "--run", "no/such/run"], 2),
    (["export", "--run", "no/such/run", "--format", "csv"], 2),
])
def test_commands_that_do_not_train_import_neither_torch_nor_ray(argv: list[str], code: int, tmp_path) -> None:
    done = subprocess.run([sys.executable, "-c", PROBE, *argv], capture_output=True, text=True, cwd=tmp_path,
                          check=False)
    assert f"EXIT {code}" in done.stdout, done.stdout + done.stderr
    assert "HEAVY []" in done.stdout, f"bench {' '.join(argv)} imported {done.stdout.splitlines()[-1]}"
