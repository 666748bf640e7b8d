"""Turn-around of the command line when it does not train: wall seconds of
``bench --help``, ``bench grids``, one-line errors, a refused ``--against`` and a 10-episode
``bench eval`` at N = 8 (PIBT, and a learned method), each a fresh process (what a user
waits for), median of ``repeats``.

Targets on an idle machine: ``--help`` < 1.5 s, ``grids`` < 3 s, a one-line error < 2 s,
``eval`` of 10 episodes at N = 8 < 10 s. A loaded machine inflates every number alike:
compare commands against ``python -c pass`` (``startup``) of the same run, not across runs.

May import: nothing of the bench (it runs the ``bench`` console script).
"""
from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

# name -> bench arguments (None: the interpreter alone, the floor every command pays).
COMMANDS: dict[str, list[str] | None] = {
    "startup": None,
    "help": ["--help"],
    "grids": ["grids"],
    "error_method": ["eval", "--method", "pibtt", "--n-robots", "8"],
    "error_param": ["tune", "--study", "x", "--method", "decentralized", "--param", "nope=1,2"],
    "eval_10_n8": ["eval", "--method", "pibt", "--n-robots", "8", "--episodes", "10", "--horizon", "64"],
    # a learned method's evaluation: torch and its optimizers' set-up (bench/execute/torch_setup.py)
    "eval_10_n8_learned": ["eval", "--method", "decentralized", "--n-robots", "8", "--episodes", "10",
                           "--horizon", "64"],
}


def _bench() -> list[str]:
    """The ``bench`` console script beside this interpreter, else ``python -m bench.cli``."""
    script = Path(sys.executable).with_name("bench")
    return [str(script)] if script.exists() else [sys.executable, "-c", "from bench.cli import main; main()"]


def time_command(argv: list[str] | None, repeats: int = 3) -> dict[str, float]:
    """Median and minimum wall seconds of ``bench ARGV`` in a fresh process, and its exit status."""
    cmd = [sys.executable, "-c", "pass"] if argv is None else [*_bench(), *argv]
    times, code = [], 0
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "OMP_NUM_THREADS": "1"}
        for _ in range(repeats):
            t0 = time.perf_counter()
            code = subprocess.run(cmd, cwd=tmp, env=env, capture_output=True, check=False).returncode
            times.append(time.perf_counter() - t0)
    return {"median_s": statistics.median(times), "min_s": min(times), "exit": code}


def run_cli_suite(repeats: int = 3, reproduction: Path | None = None) -> pd.DataFrame:
    """One row per command of ``COMMANDS``, and ``against_refused`` where the committed
    ``reproduction`` folder is found (default: ./reproduction): ``report --run
    reproduction/ablation --against reproduction/paper``, refused (their horizons differ)."""
    rows = [{"suite": "cli", "command": name, **time_command(argv, repeats)} for name, argv in COMMANDS.items()]
    root = (reproduction or Path("reproduction")).resolve()
    if (root / "ablation").is_dir() and (root / "paper").is_dir():
        with tempfile.TemporaryDirectory() as out:
            argv = ["report", "--run", str(root / "ablation"), "--against", str(root / "paper"), "--out", out]
            rows.append({"suite": "cli", "command": "against_refused", **time_command(argv, repeats)})
    return pd.DataFrame(rows)


if __name__ == "__main__":
    with pd.option_context("display.width", 200, "display.precision", 3):
        print(run_cli_suite().to_string(index=False))
