"""The store and the resume plan with execution modes (no Ray): a finished cell holds one
eval row per episode and mode, every mode on the same scenarios; a cell whose eval file
lacks a mode is not done (it is re-evaluated), and the report lists it."""
from __future__ import annotations

from pathlib import Path

from bench.design import costs
from bench.design.cells import Cell
from bench.design.grid_files import load_grid_file
from bench.design.grids import Grid
from bench.execute.plan import plan_run
from bench.store.run_store import RunStore
from reports.data.store import load_store
from tests.bench.conftest import toy_spec, write_finished_store, write_grid_file

MODES = ["argmax", "sample", "sample@0.5"]


def _finished(tmp_path: Path, **kw: object) -> tuple[Grid, RunStore]:
    grid = Grid("toygrid", "test", tuple(Cell.make(**toy_spec(seed=s, **kw)) for s in (0, 1)))
    write_finished_store(tmp_path / "run", grid)
    return grid, RunStore(tmp_path / "run")


def test_store__one_row_per_episode_and_mode_on_the_same_scenarios(toy: str, tmp_path: Path) -> None:
    grid, store = _finished(tmp_path)
    ev = store.read_eval()
    assert len(ev) == 2 * 5 * 3 and not ev.duplicated(["cell_id", "execution", "episode"]).any()
    for _, g in ev.groupby("cell_id"):
        assert sorted(g["execution"].unique()) == sorted(MODES)
        wide = g.pivot(index="episode", columns="execution", values="scenario")
        assert (wide.nunique(axis=1) == 1).all()  # paired: one scenario per episode in every mode
        assert wide.index.tolist() == list(range(5))
    cells = store.read_cells()
    assert (cells["executions"] == ",".join(MODES)).all()
    states, _ = plan_run(store, grid, fresh=False)
    assert all(st.phase == "done" for st in states)


def test_plan__a_cell_missing_a_mode_is_reevaluated_and_the_report_lists_it(toy: str, tmp_path: Path) -> None:
    grid, store = _finished(tmp_path)
    victim = grid.cells[0].cell_id
    ev = store.read_eval()
    part = ev[(ev.cell_id == victim) & (ev.execution != "sample@0.5")]
    store.write_eval(victim, part.to_dict("records"), {"wall_s": 1.0})
    problems = load_store(store.root).problems
    assert problems == [f"cell {victim} is done but its rows are incomplete: 0 of 5 evaluation episodes in execution "
                        "mode sample@0.5"]
    states, _ = plan_run(store, grid, fresh=False)
    st = {s.cell_id: s for s in states}
    assert st[victim].phase == "pending" and st[victim].trained and st[victim].has_checkpoint
    assert st[grid.cells[1].cell_id].phase == "done"
    # one episode short in a mode is incomplete too
    store.write_eval(victim, ev[(ev.cell_id == victim) & ~((ev.execution == "sample") & (ev.episode == 4))]
                     .to_dict("records"), {"wall_s": 1.0})
    assert {s.cell_id: s.phase for s in plan_run(store, grid, fresh=False)[0]}[victim] == "pending"


def test_plan__planner_cells_have_one_mode(tmp_path: Path) -> None:
    grid = Grid("p", "test", (Cell.make(method="pibt", n_robots=4, loss_p=0.2, layout="tiny", episodes=0,
                                        horizon=10, eval_episodes=3, params={"eval_chunk": 2}),))
    write_finished_store(tmp_path / "run", grid)
    ev = RunStore(tmp_path / "run").read_eval()
    assert ev["execution"].tolist() == ["planner"] * 3
    states, _ = plan_run(RunStore(tmp_path / "run"), grid, fresh=False)
    assert states[0].phase == "done" and states[0].eval_units() == [("planner", 0), ("planner", 1)]


def test_grid_file__eval_temperatures_set_the_modes_rows_and_cost(toy: str, tmp_path: Path) -> None:
    base = {**toy_spec(), "eval_temperatures": [0.25, 2.0]}
    grid = load_grid_file(write_grid_file(tmp_path / "g.toml", base, {"seed": [0]}))
    cell = grid.cells[0]
    modes = ["argmax", "sample", "sample@2", "sample@0.25"]
    assert list(cell.execution_modes()) == modes
    _, ev = costs.cell_agent_steps(cell)
    assert ev == 4 * cell.eval_episodes * cell.horizon * cell.n_robots
    write_finished_store(tmp_path / "run", grid)
    rows = RunStore(tmp_path / "run").read_eval()
    assert rows.groupby("execution").size().to_dict() == {m: 5 for m in modes}
