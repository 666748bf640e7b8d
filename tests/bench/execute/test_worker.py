"""The worker without Ray: resuming from a checkpoint state equals training straight through,
and evaluation chunks do not depend on which worker ran them or in which order."""
from __future__ import annotations

import math

import pandas as pd
import pytest

from bench.design.cells import Cell
from bench.execute.plan import cell_spec
from bench.execute.worker import CellWorker, peak_rss_mb
from tests.bench.conftest import toy_spec

METRICS = ["episode", "team_return", "success_rate", "collision_rate", "steps", "actor_loss"]


def _train_all(worker: CellWorker, spec: dict, k: int, restart_every_chunk: bool) -> tuple[list, dict]:
    rows, state, iterations = [], None, 0
    while True:
        if restart_every_chunk:
            worker = CellWorker()  # a fresh process: only the checkpoint state carries over
        res = worker.train_chunk(spec, [state] if state is not None else [], iterations, k)
        rows += res["rows"]
        state, iterations = res["state"], res["iterations"]
        if res["finished"]:
            return rows, state


@pytest.mark.parametrize("method", ["toy", "hierarchical", "decentralized", "ic3net"])
def test_train_chunks__resuming_from_each_checkpoint_equals_one_straight_run(toy: str, method: str) -> None:
    spec_kw = toy_spec(method=method, episodes=6, horizon=10)
    if method != "toy":
        spec_kw["params"] = {"batch_episodes": 2, "eval_chunk": 2}
    spec = cell_spec(Cell.make(**spec_kw))
    straight, _ = _train_all(CellWorker(), spec, k=10, restart_every_chunk=False)
    resumed, state = _train_all(CellWorker(), spec, k=1, restart_every_chunk=True)
    cols = [c for c in METRICS if c in straight[0]]
    assert len(straight) == 6 and [r["episode"] for r in resumed] == list(range(6))
    pd.testing.assert_frame_equal(pd.DataFrame(straight)[cols], pd.DataFrame(resumed)[cols])
    assert state["episodes_done"] == 6


@pytest.mark.parametrize("method", ["toy", "decentralized"])
@pytest.mark.parametrize("mode", ["argmax", "sample", "sample@0.5"])
def test_eval_chunks__same_rows_in_any_order_and_on_any_worker(toy: str, method: str, mode: str) -> None:
    spec = cell_spec(Cell.make(**toy_spec(method=method, eval_episodes=6)))
    _, state = _train_all(CellWorker(), spec, k=10, restart_every_chunk=False)
    one = CellWorker()
    one.eval_chunk(spec, [state], 1, "sample")  # another mode first on the same worker
    forward = [r for c in (0, 1, 2) for r in one.eval_chunk(spec, [state], c, mode)["rows"]]
    backward = {c: CellWorker().eval_chunk(spec, [state], c, mode)["rows"] for c in (2, 1, 0)}
    again = [r for c in (0, 1, 2) for r in backward[c]]
    assert [r["episode"] for r in forward] == list(range(6))
    assert {r["execution"] for r in forward} == {mode}
    assert pd.DataFrame(forward).equals(pd.DataFrame(again))


def test_train_chunk__wrong_checkpoint_iteration_is_refused(toy: str) -> None:
    spec = cell_spec(Cell.make(**toy_spec()))
    res = CellWorker().train_chunk(spec, [], 0, 1)
    with pytest.raises(RuntimeError, match="expected 3"):
        CellWorker().train_chunk(spec, [res["state"]], 3, 1)


def test_planner__finishes_training_at_once_without_rows() -> None:
    spec = cell_spec(Cell.make(method="pibt", n_robots=4, loss_p=0.2, layout="tiny", episodes=0,
                               horizon=10, eval_episodes=2))
    res = CellWorker().train_chunk(spec, [], 0, 5)
    assert res["finished"] and res["rows"] == [] and res["episodes_done"] == 0


def test_peak_rss__is_a_positive_number_of_megabytes() -> None:
    mb = peak_rss_mb()
    assert 10.0 < mb < 100_000.0 and not math.isnan(mb)


@pytest.mark.parametrize("method", ["hierarchical", "decentralized", "ic3net"])
def test_train_stack__stacks_seeds_of_a_stackable_method_and_equals_one_by_one(toy: str, monkeypatch,
                                                                               method: str) -> None:
    """A stack of three seeds of a stackable method trains through ``train_stacked`` (one
    rollout batch per iteration) and returns, cell by cell, what ``train_chunk`` returns for
    each alone; a toy stack (not stackable) trains one by one."""
    import algorithms.common.seed_stack as stack_mod  # the worker imports it when a stack trains

    calls = []
    real = stack_mod.train_stacked
    monkeypatch.setattr(stack_mod, "train_stacked", lambda ms, view: calls.append(len(ms)) or real(ms, view))
    kw = toy_spec(method=method, episodes=4, horizon=10, params={"batch_episodes": 2, "eval_chunk": 2})
    specs = [cell_spec(Cell.make(**{**kw, "seed": s})) for s in (0, 1, 2)]
    stacked = CellWorker().train_stack(specs, [[], [], []], [0, 0, 0], 3)
    assert calls == [3, 3]  # two iterations of 2 episodes each, all three seeds in one batch
    for spec, got in zip(specs, stacked, strict=True):
        alone = CellWorker().train_chunk(spec, [], 0, 3)
        assert got["finished"] and got["iterations"] == alone["iterations"] == 2
        cols = [c for c in METRICS if c in alone["rows"][0]]
        pd.testing.assert_frame_equal(pd.DataFrame(got["rows"])[cols], pd.DataFrame(alone["rows"])[cols])
    calls.clear()
    toys = [cell_spec(Cell.make(**toy_spec(seed=s))) for s in (0, 1)]
    CellWorker().train_stack(toys, [[], []], [0, 0], 1)
    assert calls == []
