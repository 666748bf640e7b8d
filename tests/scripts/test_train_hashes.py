"""scripts/train_hashes.py: the bit-for-bit check of speed changes must see a changed number."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import torch

_spec = importlib.util.spec_from_file_location(
    "train_hashes", Path(__file__).resolve().parents[2] / "scripts" / "train_hashes.py")
hashes = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(hashes)

CASE = ("decentralized", {}, "tiny", 6, "stay")


def test_fingerprints__repeat_exactly_and_move_with_a_tiny_change_of_the_weights(monkeypatch) -> None:
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
