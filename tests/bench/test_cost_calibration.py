"""Cost estimates against what cells cost: the effective rates of a run's done cells, the
seed-stacking gain model, and the built-in rates against the committed reproduction."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bench import costs
from bench.cost_calibration import (
    merged_rates,
    observed_costs,
    observed_rates,
    rates_file,
    two_digits,
)
from bench.grids import get_grid

REPRODUCTION = Path(__file__).resolve().parents[2] / "reproduction" / "paper"


def test_observed_rates__median_per_method_phase_and_n_skipping_missing_phases() -> None:
    obs = pd.DataFrame([
        dict(method="a", n_robots=20, train_rate=1.0, eval_rate=10.0),
        dict(method="a", n_robots=20, train_rate=3.0, eval_rate=30.0),
        dict(method="a", n_robots=20, train_rate=8.0, eval_rate=20.0),
        dict(method="a", n_robots=40, train_rate=5.0, eval_rate=np.nan),
        dict(method="p", n_robots=20, train_rate=np.nan, eval_rate=7.0),
    ])
    assert observed_rates(obs) == {"a": {"train": {20: 3.0, 40: 5.0}, "eval": {20: 20.0}},
                                   "p": {"eval": {20: 7.0}}}


def test_merged_rates__observed_points_replace_a_phase_and_the_rest_stays_built_in() -> None:
    base = {"a": {"train": {20: 1.0, 100: 2.0}, "eval": {20: 3.0}}, "b": {"train": {20: 4.0}, "eval": {20: 5.0}}}
    out = merged_rates({"a": {"train": {40: 9.0}}, "new": {"eval": {20: 6.0}}}, base)
    assert out["a"] == {"train": {40: 9.0}, "eval": {20: 3.0}}
    assert out["b"] == base["b"]
    assert out["new"] == {"eval": {20: 6.0}, "train": costs.DEFAULT_RATE["train"]}
    assert base["a"]["train"] == {20: 1.0, 100: 2.0}  # not modified in place


def test_stack_gain__is_the_measured_three_seed_gain_and_the_fixed_cost_model_elsewhere() -> None:
    assert costs.stack_gain("hierarchical", 40, 1) == 1.0
    assert costs.stack_gain("hierarchical", 40, 3) == pytest.approx(1.47)
    assert costs.stack_gain("hierarchical", 100, 3) == pytest.approx(1.22)
    assert costs.stack_gain("hierarchical", 70, 3) == pytest.approx((1.47 + 1.22) / 2)
    x = 1.5 * (1 - 1 / 1.47)  # share of a cell's training that S seeds share: cost x/S + (1 - x)
    assert costs.stack_gain("hierarchical", 40, 2) == pytest.approx(1 / (x / 2 + 1 - x))
    assert 1.0 < costs.stack_gain("hierarchical", 40, 2) < 1.47 < costs.stack_gain("hierarchical", 40, 5)
    assert costs.stack_gain("ic3net", 40, 3) == 1.0  # does not stack


def test_stack_sizes__configurations_of_stackable_methods_in_stacks_of_up_to_k() -> None:
    cells = get_grid("paper").cells
    hier = [i for i, c in enumerate(cells) if c.method == "hierarchical"]
    assert costs.stack_sizes(cells, 1) == [1] * len(cells)
    three = costs.stack_sizes(cells, 3)
    assert [three[i] for i in hier] == [3] * len(hier)
    assert all(three[i] == 1 for i in range(len(cells)) if i not in hier)
    two = costs.stack_sizes(cells, 2)
    by_config: dict[str, list[int]] = {}
    for i in hier:
        by_config.setdefault(cells[i].model_copy(update={"seed": 0}).canonical_json(), []).append(two[i])
    assert all(sizes == [2, 2, 1] for sizes in by_config.values())  # seeds 0, 1 | 2


def test_grid_cost__stacking_shortens_only_the_hierarchical_training() -> None:
    cells = get_grid("paper").cells
    plain, stacked = costs.grid_cell_hours(cells), costs.grid_cell_hours(cells, stack_seeds=3)
    saved = sum(costs.cell_agent_steps(c)[0] / costs.rate(c.method, "train", c.n_robots)
                * (1 - 1 / costs.stack_gain(c.method, c.n_robots, 3))
                for c in cells if c.method == "hierarchical") / 3600
    assert saved > 0 and plain - stacked == pytest.approx(saved)


@pytest.fixture(scope="module")
def reproduction() -> pd.DataFrame:
    if not (REPRODUCTION / "cells.parquet").is_file():
        pytest.skip("no committed reproduction in this checkout")
    return observed_costs(REPRODUCTION)


def test_observed_costs__split_each_cell_into_its_training_rows_and_the_rest(reproduction: pd.DataFrame) -> None:
    from reports.store import load_store

    store = load_store(REPRODUCTION)
    assert set(reproduction["cell_id"]) == set(store.done["cell_id"])
    walls = store.done.set_index("cell_id")["wall_s"]
    row = reproduction.iloc[0]
    assert row.train_s + row.eval_s == pytest.approx(walls[row.cell_id])
    assert row.train_s == pytest.approx(store.train.loc[store.train.cell_id == row.cell_id, "wall_s"].sum())
    assert (reproduction.loc[reproduction.method != "pibt", ["train_s", "eval_s"]] > 0).all().all()


def test_builtin_rates__are_the_committed_reproductions(reproduction: pd.DataFrame) -> None:
    """Rebuild with `scripts/calibrate_costs.py reproduction/paper --write` when the
    reproduction's state is committed."""
    assert json.loads(costs.RATES_FILE.read_text()) == rates_file(reproduction, "reproduction/paper")
    for method, phases in observed_rates(reproduction).items():
        for phase, points in phases.items():
            for n, r in points.items():
                assert costs.rate(method, phase, n) == pytest.approx(r, rel=0.05), (method, phase, n)


def test_two_digits__rounds_to_two_significant_digits() -> None:
    assert [two_digits(x) for x in (0.0, 0.01234, 7.0, 12_345.0, 98_765.0, 330_000.0)] == \
        [0.0, 0.012, 7.0, 12_000.0, 99_000.0, 330_000.0]


def test_rates_file__observed_rates_keyed_by_n_in_numeric_order() -> None:
    obs = pd.DataFrame([dict(cell_id="x", method="a", n_robots=n, train_s=1.0, eval_s=1.0,
                             train_rate=1234.0 * n, eval_rate=np.nan) for n in (100, 20, 40)])
    out = rates_file(obs, "runs/x")
    assert out == {"run": "runs/x", "done_cells": 3,
                   "rates": {"a": {"train": {"20": 25_000.0, "40": 49_000.0, "100": 120_000.0}}}}
    assert list(out["rates"]["a"]["train"]) == ["20", "40", "100"]


def test_builtin_rates__fall_back_for_a_method_the_reproduction_has_not_finished(
        tmp_path: Path) -> None:
    path = tmp_path / "rates.json"
    path.write_text(json.dumps({"run": "r", "done_cells": 1, "rates": {"hierarchical": {"train": {"40": 5.0}}}}))
    rates = costs.merge_rates(costs.FALLBACK_RATES, costs.read_rates_file(path))
    assert rates["hierarchical"] == {"train": {40: 5.0}, "eval": costs.DEFAULT_RATE["eval"]}
    assert rates["pibt"] == costs.FALLBACK_RATES["pibt"]


def test_builtin_estimate__of_the_reproductions_done_cells_is_their_measured_cost(
        reproduction: pd.DataFrame) -> None:
    """Medians against totals: within 25% over the whole run (the old, 2-4x too small
    training rates fail this)."""
    cells = {c.cell_id: c for c in get_grid("paper").cells}
    done = [cells[cid] for cid in reproduction["cell_id"] if cid in cells]
    measured = (reproduction["train_s"].sum() + reproduction["eval_s"].sum()) / 3600
    assert costs.grid_cell_hours(done) == pytest.approx(measured, rel=0.25)
