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
    (["eval", "--method", "pibt", "--n-robots", "500", "--layout", "tiny"], 2),  # a cell that does not fit
    (["eval", "--method", "pibt", "--execution", "sampel"], 2),  # a misspelled mode
    (["grids", "--rates-from", "no/such/run"], 2),
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


def test_evaluating_a_learned_method_does_not_import_dynamo(tmp_path) -> None:
    """Creating (and loading) an optimizer does not pull in torch._dynamo (2-3 s):
    bench/execute/torch_setup.py; the evaluation itself is unchanged."""
    probe = PROBE.replace('("torch", "ray")', '("torch", "torch._dynamo", "ray")')
    argv = ["eval", "--method", "decentralized", "--n-robots", "4", "--layout", "tiny", "--episodes", "1",
            "--horizon", "4", "--json"]
    done = subprocess.run([sys.executable, "-c", probe, *argv], capture_output=True, text=True, cwd=tmp_path,
                          check=False)
    assert "HEAVY ['torch']" in done.stdout, done.stdout[-300:] + done.stderr[-2000:]
