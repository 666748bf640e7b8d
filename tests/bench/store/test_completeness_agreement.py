"""One completeness rule (bench/store/completeness.py ``cell_rows``): the runner's plan and
the report agree on every damage case, and both name the same gap.

Each case damages one done cell of a finished toy run; the runner (``plan_run``) must plan
that cell again exactly when the report (``load_store``) lists it as incomplete, and the
report's line must carry the gap the one rule states."""
from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pytest

from bench.design.cells import Cell
from bench.design.grids import Grid
from bench.execute.plan import plan_run
from bench.store.completeness import incomplete_cells
from bench.store.run_store import RunStore
from reports.data.store import load_store
from tests.bench.conftest import toy_spec, write_finished_store
from tests.bench.toy_method import TOY_PATH

GRID = Grid("toygrid", "test", tuple(Cell.make(**toy_spec(seed=s, method=TOY_PATH)) for s in (0, 1)))
VICTIM = GRID.cells[0].cell_id


def _rewrite_eval(store: RunStore, change: Callable[[pd.DataFrame], pd.DataFrame]) -> None:
    ev = store.read_eval()
    store.write_eval(VICTIM, change(ev[ev.cell_id == VICTIM]).to_dict("records"), {"wall_s": 1.0})


def _drop_train_part(store: RunStore) -> None:
    store.train_parts(VICTIM)[-1][1].unlink()


CASES: dict[str, tuple[Callable[[RunStore], None], str]] = {
    "intact": (lambda s: None, ""),
    "a training part missing": (_drop_train_part, "4 of 8 training rows"),
    "a mode missing": (lambda s: _rewrite_eval(s, lambda e: e[e.execution != "sample"]),
                       "0 of 5 evaluation episodes in execution mode sample"),
    "an episode missing": (lambda s: _rewrite_eval(s, lambda e: e[~((e.execution == "argmax") & (e.episode == 4))]),
                           "4 of 5 evaluation episodes in execution mode argmax"),
    "a duplicated row in place of a missing one": (
        lambda s: _rewrite_eval(s, lambda e: e.assign(episode=e.episode.where(
            ~((e.execution == "argmax") & (e.episode == 4)), 3))),
        "4 of 5 evaluation episodes in execution mode argmax, 1 duplicated evaluation rows"),
    "an extra duplicated row": (lambda s: _rewrite_eval(s, lambda e: pd.concat([e, e.iloc[:1]])),
                                "1 duplicated evaluation rows"),
    "a row of another mode": (lambda s: _rewrite_eval(s, lambda e: pd.concat([e, e.iloc[:1].assign(
        execution="sample@9")])), "1 evaluation rows of another execution mode or episode"),
    "the evaluation file missing": (lambda s: s.eval_path(VICTIM).unlink(), "no evaluation rows"),
}


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("complete") / "run"
    write_finished_store(out, GRID)
    return out


@pytest.mark.parametrize("case", list(CASES))
def test_runner_and_report__agree_on_every_damage_case(finished: Path, tmp_path: Path, case: str) -> None:
    run = tmp_path / "run"
    shutil.copytree(finished, run)
    store = RunStore(run)
    damage, gap = CASES[case]
    damage(store)
    states, _ = plan_run(store, GRID, fresh=False)
    runner_reruns = {st.cell_id for st in states if st.phase != "done"}
    report_lines = [p for p in load_store(run).problems if "rows are incomplete" in p]
    report_lists = {cid for cid in (VICTIM, GRID.cells[1].cell_id) if any(cid in p for p in report_lines)}
    assert runner_reruns == report_lists == ({VICTIM} if gap else set())
    assert incomplete_cells(store, store.read_cells()) == ({VICTIM: gap} if gap else {})
    if gap:
        assert report_lines == [f"cell {VICTIM} is done but its rows are incomplete: {gap}"]
