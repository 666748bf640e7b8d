"""The runner on an embedded 2-CPU Ray: worker-count independence, retries after a worker
dies, failing cells, resume after an interruption. Runtime: ~40 s on 2 shared cores."""
from __future__ import annotations

from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
import pytest

from bench.design.cells import Cell
from bench.design.grids import Grid
from bench.execute.runner import run_grid
from bench.store.checkpoints import checkpoint_cell
from bench.store.run_store import RunStore
from tests.bench.conftest import as_written_by_the_bench, snapshot, store_with_params, toy_spec

pytestmark = pytest.mark.usefixtures("ray_local")
METRICS = ["cell_id", "episode", "team_return", "success_rate", "collision_rate", "invalid_rate", "steps"]


def _grid(*specs: dict) -> Grid:
    return Grid("toygrid", "test", tuple(Cell.make(**s) for s in specs))


def _frames(out: Path) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    store = RunStore(out)
    key = ["cell_id", "episode"]
    ekey = ["cell_id", "execution", "episode"]
    train = store.read_train()
    evals = store.read_eval()
    return (store.read_cells().set_index("cell_id").sort_index(),
            train[METRICS + ["actor_loss"]].sort_values(key).reset_index(drop=True),
            evals[METRICS + ["execution", "scenario"]].sort_values(ekey).reset_index(drop=True))


def _four_cells() -> Grid:
    return _grid(*(toy_spec(seed=s, n_robots=n) for s in (0, 1) for n in (4, 6)))


def test_run__one_and_two_workers_give_identical_metrics_and_rerun_changes_nothing(toy: str, tmp_path: Path) -> None:
    grid = _four_cells()
    s1 = run_grid(grid, tmp_path / "w1", workers=1, checkpoint_every=1)
    s2 = run_grid(grid, tmp_path / "w2", workers=2, checkpoint_every=1)
    assert (s1.done, s1.failed, s2.done, s2.failed) == (4, 0, 4, 0)
    c1, t1, e1 = _frames(tmp_path / "w1")
    c2, t2, e2 = _frames(tmp_path / "w2")
    assert (c1["status"] == "done").all() and (c1["attempts"] == 1).all()
    assert len(t1) == 4 * 8 and len(e1) == 4 * 5 * 3  # 5 episodes in argmax, sample, sample@0.5
    assert not e1.duplicated(["cell_id", "execution", "episode"]).any()
    pd.testing.assert_frame_equal(t1, t2)
    pd.testing.assert_frame_equal(e1, e2)
    assert (c1["peak_mem_mb"] > 50).all() and (c1["wall_s"] > 0).all()
    # a rerun of a finished run skips every cell: result files byte-identical
    data = {k: v for k, v in snapshot(tmp_path / "w1").items() if k.startswith(("train", "eval", "checkpoints"))}
    again = run_grid(grid, tmp_path / "w1", workers=2, checkpoint_every=1)
    assert again.done == 4
    after = {k: v for k, v in snapshot(tmp_path / "w1").items() if k.startswith(("train", "eval", "checkpoints"))}
    assert after == data
    # every run of the folder is one manifest record: commit, machine, workers, end, wall, cells
    runs = RunStore(tmp_path / "w1").require_run()["runs"]
    assert len(runs) == 2 and runs[0]["workers"] == 1
    counts = [(r["cells_done_before"], r["cells_done_in_run"], r["cells_done_after"]) for r in runs]
    assert counts == [(0, 4, 4), (4, 0, 4)]
    first = runs[0]
    assert first["git"] and first["machine"]["cpus"] >= 1 and first["machine"]["host"]
    assert 0 < first["wall_s"] and first["started"] <= first["ended"] <= runs[1]["started"]


def test_run__interrupted_then_resumed_equals_an_uninterrupted_run(toy: str, tmp_path: Path) -> None:
    grid = _four_cells()
    seen = []

    def interrupt(kind: str, st: object) -> None:
        seen.append(kind)
        if seen.count("train_chunk") == 5:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_grid(grid, tmp_path / "a", workers=2, checkpoint_every=1, on_event=interrupt)
    cells = RunStore(tmp_path / "a").read_cells()
    assert (cells["status"] != "done").any()
    run_grid(grid, tmp_path / "a", workers=2, checkpoint_every=1)
    run_grid(grid, tmp_path / "b", workers=2, checkpoint_every=3)
    ca, ta, ea = _frames(tmp_path / "a")
    _, tb, eb = _frames(tmp_path / "b")
    cut, resumed = RunStore(tmp_path / "a").require_run()["runs"]  # the interrupted run is closed too
    assert cut["cells_done_in_run"] + resumed["cells_done_in_run"] == 4 and resumed["cells_done_after"] == 4
    assert "ended" in cut and cut["cells_done_after"] < 4
    assert (ca["status"] == "done").all()
    assert not ta.duplicated(["cell_id", "episode"]).any()
    pd.testing.assert_frame_equal(ta, tb)
    pd.testing.assert_frame_equal(ea, eb)


def test_run__worker_killed_mid_cell_is_retried_and_the_run_completes(toy: str, tmp_path: Path) -> None:
    marker = tmp_path / "killed"
    crash = toy_spec(params={"die_at_iteration": 2, "marker": str(marker)})
    grid = _grid(crash, toy_spec())
    summary = run_grid(grid, tmp_path / "run", workers=2, checkpoint_every=1)
    assert marker.exists(), "the worker process was not killed"
    assert (summary.done, summary.failed) == (2, 0)
    cells, train, evals = _frames(tmp_path / "run")
    crashed, ref = (c.cell_id for c in grid.cells)
    assert cells.loc[crashed, "attempts"] == 2 and cells.loc[ref, "attempts"] == 1
    rows = train[train.cell_id == crashed]
    assert rows["episode"].tolist() == list(range(8))  # none lost, none duplicated
    # the fault parameters do not change the numbers: the retried cell equals the reference
    cols = METRICS[1:] + ["actor_loss"]
    pd.testing.assert_frame_equal(rows[cols].reset_index(drop=True),
                                  train[train.cell_id == ref][cols].reset_index(drop=True))


def test_run__failing_cell_is_recorded_and_the_others_finish(toy: str, tmp_path: Path) -> None:
    grid = _grid(toy_spec(params={"raise_at_iteration": 1}), toy_spec(seed=5))
    bad, good = (c.cell_id for c in grid.cells)
    summary = run_grid(grid, tmp_path / "run", workers=2, checkpoint_every=1)
    assert (summary.done, summary.failed) == (1, 1)
    cells = RunStore(tmp_path / "run").read_cells().set_index("cell_id")
    assert cells.loc[bad, "status"] == "failed" and cells.loc[good, "status"] == "done"
    assert cells.loc[bad, "error"] == "RuntimeError: toy failure at iteration 1"
    assert cells.loc[good, "error"] == ""
    good_eval = RunStore(tmp_path / "run").eval_path(good).read_bytes()
    again = run_grid(grid, tmp_path / "run", workers=2, checkpoint_every=1)  # a rerun retries failures
    assert (again.done, again.failed) == (1, 1)
    cells = RunStore(tmp_path / "run").read_cells().set_index("cell_id")
    assert cells.loc[bad, "attempts"] == 2 and cells.loc[good, "attempts"] == 1
    assert RunStore(tmp_path / "run").eval_path(good).read_bytes() == good_eval


def test_run__fresh_starts_over_and_drops_cells_of_other_grids(toy: str, tmp_path: Path) -> None:
    out = tmp_path / "run"
    run_grid(_grid(toy_spec(seed=7)), out, workers=1, checkpoint_every=4)
    other = _grid(toy_spec(seed=8))
    run_grid(other, out, workers=1, checkpoint_every=4)
    assert len(RunStore(out).read_cells()) == 2  # a second grid in the same folder adds its cells
    summary = run_grid(other, out, workers=1, checkpoint_every=4, fresh=True)
    cells = RunStore(out).read_cells()
    assert summary.done == 1 and cells["cell_id"].tolist() == [other.cells[0].cell_id]
    assert sorted(checkpoint_cell(p.name) for p in (out / "checkpoints").iterdir()) == [other.cells[0].cell_id]
    assert cells["attempts"].tolist() == [1]


def test_run__done_cell_with_missing_rows_is_run_again_to_identical_rows(toy: str, tmp_path: Path) -> None:
    grid = _grid(toy_spec(seed=3), toy_spec(seed=4))
    out = tmp_path / "run"
    run_grid(grid, out, workers=2, checkpoint_every=1)
    _, train0, eval0 = _frames(out)
    store = RunStore(out)
    lost_part = store.train_parts(grid.cells[0].cell_id)[1][1]
    lost_part.unlink()  # a training part of a finished cell disappears
    short = pq.read_table(store.eval_path(grid.cells[1].cell_id))
    pq.write_table(short.slice(0, 3), store.eval_path(grid.cells[1].cell_id))  # ... and eval rows go missing
    as_written_by_the_bench(out)  # left so by the bench itself, not changed from outside (that is --repair's)
    store.integrity().forget([lost_part])
    summary = run_grid(grid, out, workers=2, checkpoint_every=1)
    assert summary.done == 2 and set(summary.rerun) == {c.cell_id for c in grid.cells}
    assert "training it again from the start" in summary.rerun[grid.cells[0].cell_id]
    assert "evaluating it again from its final checkpoint" in summary.rerun[grid.cells[1].cell_id]
    _, train1, eval1 = _frames(out)
    pd.testing.assert_frame_equal(train0, train1)
    pd.testing.assert_frame_equal(eval0, eval1)
    assert run_grid(grid, out, workers=2, checkpoint_every=1).rerun == {}


def test_run__interrupted_between_execution_modes_then_resumed_has_every_mode_once(
        toy: str, tmp_path: Path) -> None:
    grid = _grid(*(toy_spec(seed=s) for s in (0, 1)))  # 3 chunks x 3 modes = 9 eval units per cell
    seen = []

    def interrupt(kind: str, st: object) -> None:
        seen.append(kind)
        if seen.count("eval_chunk") == 4:  # some modes of a cell evaluated, others not
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_grid(grid, tmp_path / "a", workers=2, checkpoint_every=2, on_event=interrupt)
    assert (RunStore(tmp_path / "a").read_cells()["status"] != "done").all()
    run_grid(grid, tmp_path / "a", workers=2, checkpoint_every=2)
    run_grid(grid, tmp_path / "b", workers=1, checkpoint_every=2)
    ca, _, ea = _frames(tmp_path / "a")
    _, _, eb = _frames(tmp_path / "b")
    assert (ca["status"] == "done").all()
    assert len(ea) == 2 * 5 * 3 and not ea.duplicated(["cell_id", "execution", "episode"]).any()
    pd.testing.assert_frame_equal(ea, eb)


def test_run__rerun_changed_trains_a_cell_with_changed_defaults_again_and_keeps_its_old_files(
        toy: str, tmp_path: Path) -> None:
    import json

    grid = _grid(toy_spec(seed=5), toy_spec(seed=6))
    out = tmp_path / "run"
    run_grid(grid, out, workers=1, checkpoint_every=2)
    _, train0, eval0 = _frames(out)
    store = RunStore(out)
    cid = grid.cells[0].cell_id
    store_with_params(out, cid, lr=0.5)
    as_written_by_the_bench(out)  # cells.parquet as an older bench with other defaults wrote it
    old_eval = store.eval_path(cid).read_bytes()
    with pytest.raises(Exception, match="--rerun-changed"):
        run_grid(grid, out, workers=1, checkpoint_every=2)
    summary = run_grid(grid, out, workers=1, checkpoint_every=2, rerun_changed=True)
    assert summary.done == 2 and list(summary.rerun) == [cid] and "lr: 0.5 -> 0.05" in summary.rerun[cid]
    (archive,) = (out / "superseded").iterdir()
    assert archive.name.startswith(cid) and (archive / "eval.parquet").read_bytes() == old_eval
    cells, train1, eval1 = _frames(out)
    assert json.loads(cells.loc[cid, "params_json"])["lr"] == 0.05  # the row now says what ran
    # wall_s counts only the attempt that produced the cell; the discarded one has its own column
    old_wall = json.loads((archive / "cells_row.json").read_text())["wall_s"]
    assert old_wall > 0 and cells.loc[cid, "superseded_wall_s"] == old_wall
    assert cells.loc[cid, "wall_s"] == store.eval_meta(cid)["wall_s"]
    assert cells.loc[grid.cells[1].cell_id, "superseded_wall_s"] == 0.0
    pd.testing.assert_frame_equal(train0, train1)  # the same seeds and parameters: the same rows
    pd.testing.assert_frame_equal(eval0, eval1)
    assert run_grid(grid, out, workers=1, checkpoint_every=2).rerun == {}


def _hier_seeds(episodes: int = 6, **params: object) -> Grid:
    """Three seeds of one hierarchical configuration and a fourth cell that differs in N."""
    base = dict(method="hierarchical", loss_p=0.3, layout="tiny", episodes=episodes, horizon=15,
                eval_episodes=2, params={"batch_episodes": 2, "eval_chunk": 2, "hidden": 8,
                                         "critic_hidden": 8, "predictor_hidden": 8, **params})
    return _grid(*(dict(base, n_robots=4, seed=s) for s in (0, 1, 2)), dict(base, n_robots=6, seed=0))


def _stacked_as_alone(grid: Grid, tmp_path: Path, stack_seeds: int | str
                      ) -> tuple[list[tuple[str, str]], pd.DataFrame, pd.DataFrame]:
    """Run ``grid`` unstacked on 2 workers (tmp_path/alone) and with ``stack_seeds`` on one
    (tmp_path/stacked): every cell done, the same train and eval rows. Returns the stacked
    run's (event, cell id) and the unstacked run's train and eval frames."""
    alone = run_grid(grid, tmp_path / "alone", workers=2, checkpoint_every=1)
    events: list[tuple[str, str]] = []
    stacked = run_grid(grid, tmp_path / "stacked", workers=1, checkpoint_every=1, stack_seeds=stack_seeds,
                       on_event=lambda kind, st: events.append((kind, st.cell_id)))
    assert (alone.done, stacked.done) == (len(grid.cells), len(grid.cells))
    _, ta, ea = _frames(tmp_path / "alone")
    _, ts, es = _frames(tmp_path / "stacked")
    pd.testing.assert_frame_equal(ta, ts)
    pd.testing.assert_frame_equal(ea, es)
    return events, ta, ea


def test_run__stacked_seeds_give_the_numbers_of_cells_trained_one_by_one(tmp_path: Path) -> None:
    """--stack-seeds 3: the three seeds of a configuration train in one worker with one rollout
    batch (algorithms/common/seed_stack.py); every row is what the unstacked run stores, and an
    interrupted stacked run resumes to the same rows."""
    grid = _hier_seeds()
    stacked_events, ta, ea = _stacked_as_alone(grid, tmp_path, 3)
    cs = _frames(tmp_path / "stacked")[0]
    # the three seeds started together (one stack, before any chunk came back), the N = 6
    # cell on its own after them
    seeds = {c.cell_id for c in grid.cells[:3]}
    assert [kind for kind, _ in stacked_events[:4]] == ["started"] * 3 + ["train_chunk"]
    assert {cid for _, cid in stacked_events[:3]} == seeds
    starts = [cid for kind, cid in stacked_events if kind == "started"]
    assert starts[3] == grid.cells[3].cell_id
    assert (cs["wall_s"] > 0).all()

    seen = []

    def interrupt(kind: str, st: object) -> None:
        seen.append(kind)
        if seen.count("train_chunk") == 4:  # the stack's second chunk, part-way through it
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_grid(grid, tmp_path / "cut", workers=1, checkpoint_every=1, stack_seeds=3, on_event=interrupt)
    run_grid(grid, tmp_path / "cut", workers=1, checkpoint_every=1, stack_seeds=3)
    _, tc, ec = _frames(tmp_path / "cut")
    pd.testing.assert_frame_equal(ta, tc)
    pd.testing.assert_frame_equal(ea, ec)


def test_run__auto_stacking_runs_the_longest_cell_first_alone_and_stacks_the_rest(tmp_path: Path) -> None:
    """--stack-seeds auto with one worker: the longest cell (N = 6) trains first, alone; the
    three seeds of the shared-parameter configuration then train as one stack; the rows are
    the unstacked run's, the run record lists the stack, and a run cut part-way and resumed
    with --stack-seeds 1 (stacking changed on resume) stores them too."""
    grid = _hier_seeds(share_params=True)
    events, ta, ea = _stacked_as_alone(grid, tmp_path, "auto")
    starts = [cid for kind, cid in events if kind == "started"]
    seeds = [c.cell_id for c in grid.cells[:3]]
    assert starts[0] == grid.cells[3].cell_id and set(starts[1:4]) == set(seeds)
    first_seed = events.index(("started", starts[1]))
    assert [kind for kind, _ in events[first_seed:first_seed + 4]] == ["started"] * 3 + ["train_chunk"]
    record = RunStore(tmp_path / "stacked").read_manifest()["runs"][-1]
    assert record["stack_seeds"] == "auto" and record["stacks"] == [starts[1:4]]
    assert "stack_seeds" not in RunStore(tmp_path / "alone").read_manifest()["runs"][-1]

    seen = []

    def interrupt(kind: str, st: object) -> None:
        seen.append(kind)
        if seen.count("train_chunk") == 5:  # the stack's first chunks are in
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_grid(grid, tmp_path / "cut", workers=1, checkpoint_every=1, stack_seeds="auto", on_event=interrupt)
    run_grid(grid, tmp_path / "cut", workers=2, checkpoint_every=1, stack_seeds=1)
    _, tc, ec = _frames(tmp_path / "cut")
    pd.testing.assert_frame_equal(ta, tc)
    pd.testing.assert_frame_equal(ea, ec)
