"""The loss rule (a probability in [0, 1], a known loss model, bursts of at least one step,
and a Gilbert-Elliott mean loss its bursts allow) is one function, ``envs.config.loss_error``,
called where a loss enters: ``EnvConfig`` (the environment, and every cell, which validates
through its EnvConfig) and ``bench matrix``'s options. Nothing downstream checks it again.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from bench.design.cells import Cell
from envs.config import EnvConfig, loss_error
from envs.errors import BenchError
from tests.source_scan import code_matches

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("envs", "algorithms", "bench", "reports", "studies", "paper", "scripts")
CALLS = re.compile(r"\b(loss_error|bursty_loss_error|max_bursty_loss)\(")
ENTRIES = {"envs/config.py", "bench/execute/matrix.py"}  # EnvConfig; bench matrix --p/--loss-model/--burst


def rule_callers(base: Path, folders: tuple[str, ...]) -> set[str]:
    """Files under ``base / folder`` that call the loss rule (comments and definitions ignored)."""
    return {rel for rel, _, code in code_matches(base, folders, CALLS) if not code.lstrip().startswith("def ")}


def test_the_loss_rule_is_called_only_where_a_loss_enters():
    assert rule_callers(ROOT, PACKAGES) == ENTRIES


def test_rule_callers__finds_a_second_check(tmp_path):
    (tmp_path / "algorithms").mkdir()
    (tmp_path / "algorithms" / "m.py").write_text("def f(p):\n    # loss_error(p) in a comment\n    return 1\n"
                                                   "why = bursty_loss_error(p, 4.0)\n")
    assert rule_callers(tmp_path, ("algorithms",)) == {"algorithms/m.py"}


@pytest.mark.parametrize(("args", "names", "why"), [
    ((1.5, "bernoulli", 4.0), ("loss_p",), "must be in [0, 1]"),
    ((float("nan"), "bernoulli", 4.0), ("loss_p",), "must be in [0, 1]"),
    ((0.2, "pareto", 4.0), ("loss_model",), "unknown loss model"),
    ((0.2, "gilbert_elliott", 0.5), ("burst_length",), ">= 1 step"),
    ((0.9, "gilbert_elliott", 4.0), ("loss_p", "burst_length"), "at most 0.8"),
])
def test_loss_error__names_the_inputs_at_fault(args, names, why):
    found = loss_error(*args)
    assert found is not None and found[0] == names and why in found[1]


@pytest.mark.parametrize("args", [(0.0, "bernoulli", 1.0), (1.0, "gilbert_elliott", 1.0),
                                  (0.8, "gilbert_elliott", 4.0)])
def test_loss_error__accepts_a_loss_process(args):
    assert loss_error(*args) is None


def test_a_cell_is_refused_by_the_environments_rule_in_one_line():
    with pytest.raises(BenchError) as err:
        Cell.make(method="pibt", n_robots=8, loss_p=0.9, loss_model="gilbert_elliott", layout="tiny")
    msg = str(err.value)
    assert msg.startswith("invalid cell: loss_p=0.9 with burst_length=4: mean loss 0.9") and "\n" not in msg
    with pytest.raises(BenchError, match="loss_p=0.9 with burst_length=4"):
        EnvConfig.make(loss_p=0.9, loss_model="gilbert_elliott")
