"""scripts/train_hashes.py: the bit-for-bit check of speed changes must see a changed number."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
import torch

_spec = importlib.util.spec_from_file_location(
    "train_hashes", Path(__file__).resolve().parents[2] / "scripts" / "train_hashes.py")
hashes = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(hashes)

CASE = ("decentralized", {}, "tiny", 6, "stay")


@pytest.fixture
def one_thread():
    """One torch thread, as the script and every bench worker run (two spin under load)."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def test_fingerprints__repeat_exactly_and_move_with_a_tiny_change_of_the_weights(monkeypatch, one_thread) -> None:
    first = hashes.fingerprints(*CASE)
    assert hashes.fingerprints(*CASE) == first  # the same code gives the same bits
    # A tiny change of the initial weights (1e-5 of each Linear's first weight: a single ulp
    # can be absorbed by float32 rounding downstream, depending on the thread count) shows
    # up in the training rows (their losses) and the parameters; the evaluation rows are
    # rates and counts, which it need not move.
    init = torch.nn.Linear.reset_parameters

    def nudged(self: torch.nn.Linear) -> None:
        init(self)
        with torch.no_grad():
            self.weight.view(-1)[0] *= 1.0 + 1e-5

    monkeypatch.setattr(torch.nn.Linear, "reset_parameters", nudged)
    changed = hashes.fingerprints(*CASE)
    assert changed["train"] != first["train"] and changed["params"] != first["params"]


_THREADS = """
import json, sys, torch
sys.path.insert(0, "scripts")
import train_hashes
case = ("decentralized", {}, train_hashes.MAP, 24, "remove")
out = {}
for key, threads in (("one", 1), ("two", 2), ("two again", 2)):
    torch.set_num_threads(threads)
    out[key] = train_hashes.fingerprints(*case)
print(json.dumps(out))
"""


@pytest.mark.slow  # a fresh process training 3 times: about 10 s alone, minutes on a loaded 2-core box
def test_fingerprints__two_threads_repeat_exactly_but_are_not_one_threads() -> None:
    """What docs/decisions/0242 rests on: on two torch threads (bench run --cell-threads 2) a
    training is a deterministic function of its inputs and the count (the same bits twice), and
    not bit for bit one thread's (its weight gradients are summed in another order), which is
    why a cell records its count. A fresh process whose OpenMP threads sleep when idle, as a
    bench worker's (OMP_WAIT_POLICY=PASSIVE, bench/execute/torch_setup.py)."""
    import json
    import os
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "OMP_WAIT_POLICY": "PASSIVE"}
    run = subprocess.run([sys.executable, "-c", _THREADS], cwd=root, env=env, capture_output=True, text=True,
                         check=True)
    got = json.loads(run.stdout.strip().splitlines()[-1])
    assert got["two"] == got["two again"]
    assert got["two"]["params"] != got["one"]["params"]

