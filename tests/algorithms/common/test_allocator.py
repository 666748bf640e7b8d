"""The glibc allocator tuning: on by default on Linux, off with WAREHOUSE_BENCH_MALLOC_TUNE=0.

Runtime: about 2 s (two fresh interpreters).
"""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

CHECK = "from algorithms.common.allocator import tune_allocator as t; print(t(), t())"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc only")
@pytest.mark.parametrize(("flag", "want"), [("1", "True True"), ("0", "False False")])
def test_tune_allocator__sets_thresholds_unless_disabled(flag: str, want: str) -> None:
    env = {**os.environ, "WAREHOUSE_BENCH_MALLOC_TUNE": flag}
    out = subprocess.run([sys.executable, "-c", CHECK], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == want
