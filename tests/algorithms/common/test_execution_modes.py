"""Execution modes (algorithms/common/execution.py): every learned method evaluates in argmax,
sample and sample@T on the same scenarios and loss draws; argmax is deterministic; the
temperature is honoured; both levels of the hierarchical method follow the mode; a mode
typo is a clear BenchError. Runtime: about 15 s on one core."""
from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import pytest
import torch

from algorithms.base import Method
from algorithms.common.episodes import EVAL_STREAM, EpisodeBatch, batch_rng
from algorithms.common.execution import (
    ActionChoice,
    ExecutionMode,
    action_generator,
    learned_modes,
    parse_execution,
    sample_categorical,
)
from algorithms.registry import method_class
from bench.design.cells import Cell
from envs.channel import LossProcess
from envs.config import EnvConfig
from envs.errors import BenchError

ENV = EnvConfig(n_robots=8, layout="tiny", horizon=16, groups=2, loss_p=0.4)
PARAMS = {"batch_episodes": 2, "eval_chunk": 4}
LEARNED = ("hierarchical", "decentralized", "ic3net")
MODES = learned_modes((0.5,))


def make(name: str, seed: int = 2) -> Method:
    return method_class(name)(ENV, PARAMS, seed=seed)


@contextmanager
def recorded_loss_draws() -> Iterator[list[np.ndarray]]:
    """Every LossProcess.step() output while the block runs, in order."""
    seen: list[np.ndarray] = []
    original: Callable[[LossProcess], np.ndarray] = LossProcess.step

    def step(self: LossProcess) -> np.ndarray:
        out = original(self)
        seen.append(out.copy())
        return out

    LossProcess.step = step  # type: ignore[method-assign]
    try:
        yield seen
    finally:
        LossProcess.step = original  # type: ignore[method-assign]


# ------------------------------------------------------------- sampling kernel
def test_sample_categorical__temperature_sharpens_the_distribution_as_softmax_of_logits_over_t() -> None:
    logits = torch.log(torch.tensor([0.6, 0.4])).expand(40_000, 2)
    gen = torch.Generator().manual_seed(0)
    freq = {t: float((sample_categorical(logits, t, gen) == 0).double().mean()) for t in (1.0, 0.5, 2.0)}
    # softmax(log p / T): T = 1 -> 0.6; T = 0.5 -> 0.36 / 0.52 = 0.692; T = 2 -> 0.550 (sd ~ 0.0025)
    assert freq[1.0] == pytest.approx(0.6, abs=0.01)
    assert freq[0.5] == pytest.approx(0.36 / 0.52, abs=0.01)
    assert freq[2.0] == pytest.approx(np.sqrt(0.6) / (np.sqrt(0.6) + np.sqrt(0.4)), abs=0.01)
    assert sample_categorical(logits[:3], None, None).tolist() == [0, 0, 0]  # argmax


def test_sample_categorical__masked_actions_stay_impossible_at_low_temperature() -> None:
    logits = torch.tensor([[0.0, -1e9, 0.0, -1e9, 0.0]]).expand(5000, 5)
    out = sample_categorical(logits, 0.25, torch.Generator().manual_seed(1))
    assert set(out.unique().tolist()) == {0, 2, 4}


def test_parse_execution__names_and_typos() -> None:
    assert parse_execution("argmax") == ExecutionMode("argmax", None)
    assert parse_execution("sample") == ExecutionMode("sample", 1.0)
    assert parse_execution("sample@0.50") == ExecutionMode("sample@0.5", 0.5)
    assert parse_execution("sample@1") == ExecutionMode("sample", 1.0)
    assert MODES == ("argmax", "sample", "sample@0.5")
    for bad in ("argmx", "sample@0", "sample@-1", "sample@x", "sampled", ""):
        with pytest.raises(BenchError, match="unknown execution mode"):
            parse_execution(bad)


def test_action_generator__is_its_own_stream_per_chunk() -> None:
    draw = lambda g: torch.rand(4, generator=g)  # noqa: E731
    assert torch.equal(draw(action_generator(3, 1)), draw(action_generator(3, 1)))
    assert not torch.equal(draw(action_generator(3, 1)), draw(action_generator(3, 2)))
    assert not torch.equal(draw(action_generator(3, 1)), draw(action_generator(4, 1)))


# ------------------------------------------------------------ every learned method
@pytest.mark.parametrize("name", LEARNED)
def test_modes__same_scenarios_and_loss_draws_in_every_mode(name: str) -> None:
    m = make(name)
    rows, draws = {}, {}
    for mode in MODES:
        with recorded_loss_draws() as seen:
            rows[mode] = m.evaluate(1, execution=mode)
        draws[mode] = seen
    ref = EpisodeBatch(ENV, PARAMS["eval_chunk"], batch_rng(m.seed, EVAL_STREAM, 1), m.layout)
    for mode in MODES:
        assert [r["execution"] for r in rows[mode]] == [mode] * PARAMS["eval_chunk"]
        assert [r["episode"] for r in rows[mode]] == [4, 5, 6, 7]
        assert [r["scenario"] for r in rows[mode]] == ref.scenario_hashes()
        # The t-th loss draw of the chunk is the same array in every mode (for as long as
        # both modes ran): the channel never sees which actions were taken.
        n = min(len(draws[mode]), len(draws["argmax"]))
        assert n > 0
        for a, b in zip(draws[mode][:n], draws["argmax"][:n], strict=True):
            assert np.array_equal(a, b)
    frames = {mode: pd.DataFrame(r).drop(columns=["execution"]) for mode, r in rows.items()}
    assert not frames["argmax"].equals(frames["sample"])  # the modes act differently
    assert not frames["sample"].equals(frames["sample@0.5"])


@pytest.mark.parametrize("name", LEARNED)
def test_modes__argmax_is_deterministic_and_sampled_modes_reproduce(name: str) -> None:
    a, b = make(name), make(name)
    b.evaluate(0, execution="sample")  # another chunk in another mode first: no influence
    b.train_iteration()  # nor does training move the evaluation streams (weights do: reload)
    b.load_state_dict(a.state_dict())
    for mode in MODES:
        pd.testing.assert_frame_equal(pd.DataFrame(a.evaluate(2, execution=mode)),
                                      pd.DataFrame(b.evaluate(2, execution=mode)))
    pd.testing.assert_frame_equal(pd.DataFrame(a.evaluate(2)),  # the default mode
                                  pd.DataFrame(a.evaluate(2, execution="argmax")))


@dataclass(frozen=True)
class RecordingChoice(ActionChoice):
    """An ActionChoice that records (logits, picked) of every call."""

    calls: list[tuple[torch.Tensor, torch.Tensor]] = field(default_factory=list)

    def __call__(self, logits: torch.Tensor) -> torch.Tensor:
        out = super().__call__(logits)
        self.calls.append((logits.clone(), out.clone()))
        return out


def _record(name: str, mode: str) -> RecordingChoice:
    m = make(name)
    ex = parse_execution(mode)
    choice = RecordingChoice(ex, None if ex.greedy else action_generator(0, 0))
    batch = EpisodeBatch(ENV, 3, batch_rng(0, EVAL_STREAM, 0), m.layout)
    with torch.no_grad():
        m.run(batch, choice)
    return choice


@pytest.mark.parametrize("name", LEARNED)
def test_modes__every_action_of_the_method_is_picked_by_the_mode(name: str) -> None:
    greedy = _record(name, "argmax")
    assert greedy.calls
    for logits, picked in greedy.calls:
        assert torch.equal(picked, logits.argmax(-1))
    sampled = _record(name, "sample@0.5")
    assert any(not torch.equal(p, lg.argmax(-1)) for lg, p in sampled.calls)


def test_hierarchical__both_levels_follow_the_mode() -> None:
    """r ~ mu (Z, B, |R|) and U~ ~ pi (Z, B, n, 5) both go through the mode's choice."""
    ref_size = 8
    for mode in ("argmax", "sample"):
        calls = _record("hierarchical", mode).calls
        levels = [lg.shape[-1] for lg, _ in calls]
        assert levels.count(ref_size) == levels.count(5) > 0  # once per step each
        if mode == "sample":
            refs = [(lg, p) for lg, p in calls if lg.shape[-1] == ref_size]
            assert any(not torch.equal(p, lg.argmax(-1)) for lg, p in refs)


# ------------------------------------------------------------------ errors
def test_modes__typo_or_wrong_kind_of_mode_is_a_clear_bench_error() -> None:
    m = make("decentralized")
    with pytest.raises(BenchError, match="decentralized execution: unknown execution mode 'argmx'"):
        m.evaluate(0, execution="argmx")
    with pytest.raises(BenchError, match="'planner' does not apply to a learned method"):
        m.evaluate(0, execution="planner")
    pibt = method_class("pibt")(ENV, {"eval_chunk": 2}, seed=0)
    assert {r["execution"] for r in pibt.evaluate(0)} == {"planner"}
    with pytest.raises(BenchError, match="'argmax' does not apply to a planner"):
        pibt.evaluate(0, execution="argmax")
    with pytest.raises(BenchError, match="execution is not a method parameter"):
        make_params = {**PARAMS, "execution": "sample"}
        method_class("ic3net")(ENV, make_params, seed=0)


@pytest.mark.parametrize("temps, error", [([1.0], "temperature 1 is the 'sample' mode"),
                                          ([0.0], "must be a finite number > 0"),
                                          ([0.5, 0.5], "duplicate temperature")])
def test_cell__bad_eval_temperatures_are_refused_naming_the_field(temps: list[float], error: str) -> None:
    with pytest.raises(BenchError, match=f"eval_temperatures: .*{error}"):
        Cell.make(method="hierarchical", n_robots=8, loss_p=0.2, layout="tiny", eval_temperatures=temps)


def test_cell__modes_follow_eval_temperatures_and_the_kind_of_method() -> None:
    cell = Cell.make(method="ic3net", n_robots=8, loss_p=0.2, layout="tiny", eval_temperatures=[0.25, 0.5])
    assert cell.execution_modes() == ("argmax", "sample", "sample@0.5", "sample@0.25")
    same = Cell.make(method="ic3net", n_robots=8, loss_p=0.2, layout="tiny", eval_temperatures=[0.5, 0.25])
    assert same.cell_id == cell.cell_id  # canonical order
    assert Cell.make(method="pibt", n_robots=8, loss_p=0.2, layout="tiny").execution_modes() == ("planner",)
