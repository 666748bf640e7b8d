"""Cost estimates against what cells cost: the effective rates of a run's done cells, the
seed-stacking gain model, and the built-in rates against the committed reproduction."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bench.design import costs
from bench.design.cost_calibration import (
    estimate_vs_realized,
    merged_rates,
    observed_costs,
    observed_rates,
    rates_file,
    two_digits,
)
from bench.design.grids import get_grid

REPRODUCTION = Path(__file__).resolve().parents[3] / "reproduction" / "paper"


def _hierarchical_seeds(grid: list) -> list:
    """The three seeds of the hierarchical method at N = 40, p = 0.2: one stack of 3."""
    return [c for c in grid if c.method == "hierarchical" and c.n_robots == 40 and c.loss_p == 0.2][:3]


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
    assert costs.stack_gain("ic3net", 40, 3) == 1.0  # stacks, but no measured gain


def test_stack_sizes__configurations_of_stackable_methods_in_stacks_of_up_to_k() -> None:
    cells = get_grid("paper").cells
    hier = [i for i, c in enumerate(cells) if c.method in ("hierarchical", "decentralized", "ic3net")]
    assert costs.stack_sizes(cells, 1) == [1] * len(cells)
    three = costs.stack_sizes(cells, 3)
    assert [three[i] for i in hier] == [3] * len(hier)
    assert all(three[i] == 1 for i in range(len(cells)) if i not in hier)
    two = costs.stack_sizes(cells, 2)
    by_config: dict[str, list[int]] = {}
    for i in hier:
        by_config.setdefault(cells[i].model_copy(update={"seed": 0}).canonical_json(), []).append(two[i])
    assert all(sizes == [2, 2, 1] for sizes in by_config.values())  # seeds 0, 1 | 2


def test_parse_stack_seeds__auto_or_a_count_of_at_least_one() -> None:
    assert costs.parse_stack_seeds("auto") == costs.parse_stack_seeds(" AUTO ") == costs.AUTO
    assert costs.parse_stack_seeds("3") == costs.parse_stack_seeds(3) == 3
    for bad in ("0", "-2", "two", ""):
        with pytest.raises(ValueError, match="give auto or a count of at least 1"):
            costs.parse_stack_seeds(bad)


def test_auto_stacking__the_longest_cells_alone_first_and_stacks_only_where_they_pay() -> None:
    """The ``workers`` longest cells run first, alone, longest first (ties in grid order);
    the others stack in threes only when more stackable cells than workers are left."""
    seconds = [5.0, 9.0, 1.0, 9.0, 2.0, 2.0, 2.0]
    stackable = [True, True, True, True, False, True, True]
    assert costs.auto_stacking(seconds, stackable, 2) == ([1, 3], costs.AUTO_STACK)  # 4 stackable left > 2
    assert costs.auto_stacking(seconds, stackable, 1) == ([1], costs.AUTO_STACK)
    assert costs.auto_stacking(seconds, stackable, 4) == ([1, 3, 0, 4], 1)  # 3 left, 4 workers: no stacks
    assert costs.auto_stacking([], [], 2) == ([], 1)


def test_stack_sizes__auto_keeps_the_grids_longest_cells_alone() -> None:
    """On the paper grid with 2 workers: the two longest cells (hierarchical, N = 100) alone,
    every other hierarchical cell stacked, the same stacks as --stack-seeds 3 elsewhere; the
    decentralized and IC3Net cells, which stack but with no measured gain (``STACK_GAIN_3``),
    alone; with
    more workers than hierarchical cells nothing stacks."""
    cells = get_grid("paper").cells
    sizes, three = costs.stack_sizes(cells, costs.AUTO, 2), costs.stack_sizes(cells, 3)
    longest = sorted(range(len(cells)), key=lambda i: -costs.cell_seconds(cells[i]))[:2]
    assert all(cells[i].method == "hierarchical" and cells[i].n_robots == 100 for i in longest)
    assert [sizes[i] for i in longest] == [1, 1]
    mates = [i for i, c in enumerate(cells) if i not in longest and c.model_copy(update={"seed": 0})
             == cells[longest[0]].model_copy(update={"seed": 0})]
    assert all(sizes[i] == 1 + (len(mates) > 1) for i in mates)  # what is left of their stack
    others = [i for i in range(len(cells)) if i not in longest and i not in mates]
    assert [sizes[i] for i in others] == [three[i] if cells[i].method == "hierarchical" else 1 for i in others]
    assert all(any(three[i] == 3 for i in others if cells[i].method == m) for m in ("decentralized", "ic3net"))
    assert costs.stack_sizes(cells, costs.AUTO, 100) == [1] * len(cells)
    assert costs.grid_cell_hours(cells, stack_seeds=costs.AUTO, workers=2) < costs.grid_cell_hours(cells)


def test_recorded_stacks__the_stacks_a_run_record_lists_override_the_formed_ones() -> None:
    """A run made with --stack-seeds auto lists its stacks in its run record: a cell's stack
    is the last one listed; the calibration scales those cells, and only those."""
    from bench.design import cost_calibration

    assert cost_calibration.recorded_stacks(None) == {}
    manifest = {"runs": [{"stacks": [["a", "b", "c"]]}, {"workers": 2}, {"stacks": [["a", "b"]]}]}
    assert cost_calibration.recorded_stacks(manifest) == {"a": 2, "b": 2, "c": 3}
    h = _hierarchical_seeds(get_grid("paper").cells)
    cells = pd.DataFrame([dict(cell_id=c.cell_id, status="done", wall_s=200.0, config_json=c.canonical_json())
                          for c in h])
    train = pd.DataFrame(dict(cell_id=[c.cell_id for c in h], wall_s=[100.0] * 3))
    out = cost_calibration.costs_of(cells, train, recorded={h[0].cell_id: 2, h[1].cell_id: 2})
    assert list(out["stack"]) == [2, 2, 1]
    assert out["train_rate"][0] == pytest.approx(out["train_rate"][2] / costs.stack_gain("hierarchical", 40, 2))


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
    from reports.data.store import load_store

    store = load_store(REPRODUCTION)
    assert set(reproduction["cell_id"]) == set(store.done["cell_id"])
    walls = store.done.set_index("cell_id")["wall_s"]
    row = reproduction.iloc[0]
    assert row.train_s + row.eval_s == pytest.approx(walls[row.cell_id])
    assert row.train_s == pytest.approx(store.train.loc[store.train.cell_id == row.cell_id, "wall_s"].sum())
    assert (reproduction.loc[reproduction.method != "pibt", ["train_s", "eval_s"]] > 0).all().all()
    assert (reproduction["stack"] == 1).all() and reproduction["trained_here"].all()  # by default: no stacks


def test_observed_costs__a_folder_without_a_store_is_named(tmp_path: Path) -> None:
    from envs.errors import BenchError

    with pytest.raises(BenchError, match=f"no results store at '{tmp_path}': cells.parquet not found"):
        observed_costs(tmp_path)


def test_observed_costs__seconds_and_effective_rates_of_each_done_cell() -> None:
    """A learned cell's training seconds are its training rows' sum and the rest of its wall
    time is evaluation; a planner without training rows trains 0 s at no rate; a phase
    under a second still gets its rate; pending cells are left out."""
    from bench.design import cost_calibration

    grid = get_grid("paper").cells
    learned = next(c for c in grid if c.method == "decentralized")
    planner = next(c for c in grid if c.method == "pibt")
    pending = next(c for c in grid if c.method == "ic3net")
    cells = pd.DataFrame([dict(cell_id=c.cell_id, status=s, wall_s=w, config_json=c.canonical_json())
                          for c, s, w in ((pending, "running", 9.0), (learned, "done", 100.5),
                                          (planner, "done", 0.25))])
    train = pd.DataFrame(dict(cell_id=[learned.cell_id] * 3 + [pending.cell_id], wall_s=[40.0, 50.0, 10.0, 5.0]))
    out = cost_calibration.costs_of(cells, train)
    assert list(out.columns) == ["cell_id", "method", "n_robots", "train_s", "eval_s", "train_rate", "eval_rate",
                                 "stack", "trained_here"]
    assert list(out["stack"]) == [1, 1] and list(out["trained_here"]) == [True, True]
    assert list(out["cell_id"]) == [learned.cell_id, planner.cell_id]
    assert list(out["method"]) == ["decentralized", "pibt"]
    assert list(out["n_robots"]) == [learned.n_robots, planner.n_robots]
    assert list(out["train_s"]) == [100.0, 0.0] and list(out["eval_s"]) == [0.5, 0.25]
    (lt, le), (_, pe) = costs.cell_agent_steps(learned), costs.cell_agent_steps(planner)
    assert out["train_rate"][0] == pytest.approx(lt / 100.0) and np.isnan(out["train_rate"][1])
    assert list(out["eval_rate"]) == pytest.approx([le / 0.5, pe / 0.25])


def test_observed_costs__a_stacked_cells_training_rate_is_scaled_back_to_one_seed() -> None:
    """Three hierarchical seeds the run trained in one stack (``--stack-seeds 3``) and a
    copied-in decentralized cell: each stacked cell's training took its share of the stack,
    so its one-seed rate is its effective rate divided by the stack's gain; a copied cell
    counts as unstacked and not trained here; without stacking nothing is scaled."""
    from bench.design import cost_calibration

    grid = get_grid("paper").cells
    h = _hierarchical_seeds(grid)
    d = next(c for c in grid if c.method == "decentralized")
    cells = pd.DataFrame([dict(cell_id=c.cell_id, status="done", wall_s=200.0, config_json=c.canonical_json())
                          for c in (*h, d)])
    train = pd.DataFrame(dict(cell_id=[c.cell_id for c in (*h, d)], wall_s=[100.0] * 4))
    out = cost_calibration.costs_of(cells, train, stack_seeds=3, copied=[d.cell_id])
    gain = costs.stack_gain("hierarchical", 40, 3)
    assert gain > 1.2
    steps = costs.cell_agent_steps(h[0])[0]
    assert list(out["stack"]) == [3, 3, 3, 1] and list(out["trained_here"]) == [True, True, True, False]
    assert list(out["train_rate"][:3]) == pytest.approx([steps / (100.0 * gain)] * 3)
    assert out["train_rate"][3] == pytest.approx(costs.cell_agent_steps(d)[0] / 100.0)
    assert list(out["eval_s"]) == [100.0] * 4
    plain = cost_calibration.costs_of(cells, train)
    assert list(plain["train_rate"][:3]) == pytest.approx([steps / 100.0] * 3)
    # An estimate at the stack the run formed gives back the stacked cell's training time.
    rates = {"hierarchical": {"train": {40: float(out["train_rate"][0])}, "eval": {40: 1e12}}}
    assert costs.cell_seconds(h[0], rates, 3) == pytest.approx(100.0, rel=1e-6)


def test_observed_rates__prefer_the_cells_the_run_trained_itself() -> None:
    """At a (method, N) where the run trained cells itself, copied-in cells do not count;
    where it trained none, they do."""
    obs = pd.DataFrame([
        dict(method="a", n_robots=20, train_rate=1.0, eval_rate=1.0, trained_here=True),
        dict(method="a", n_robots=20, train_rate=100.0, eval_rate=100.0, trained_here=False),
        dict(method="a", n_robots=20, train_rate=100.0, eval_rate=100.0, trained_here=False),
        dict(method="a", n_robots=40, train_rate=5.0, eval_rate=7.0, trained_here=False),
    ])
    assert observed_rates(obs) == {"a": {"train": {20: 1.0, 40: 5.0}, "eval": {20: 1.0, 40: 7.0}}}


def test_observed_costs__a_phase_with_no_time_has_no_rate_and_no_cells_give_no_rows() -> None:
    """Edge cells: a learned cell without training rows, one whose training took all of its
    wall time (half a second); a store without done cells still has every column."""
    from bench.design import cost_calibration

    a, b = [c for c in get_grid("paper").cells if c.method == "decentralized"][:2]
    cells = pd.DataFrame([dict(cell_id=c.cell_id, status="done", wall_s=w, config_json=c.canonical_json())
                          for c, w in ((a, 30.0), (b, 0.5))])
    train = pd.DataFrame(dict(cell_id=[b.cell_id], wall_s=[0.5]))
    out = cost_calibration.costs_of(cells, train)
    assert list(out["train_s"]) == [0.0, 0.5] and list(out["eval_s"]) == [30.0, 0.0]
    assert np.isnan(out["train_rate"][0]) and np.isnan(out["eval_rate"][1])
    assert out["train_rate"][1] == pytest.approx(costs.cell_agent_steps(b)[0] / 0.5)
    empty = cost_calibration.costs_of(cells.assign(status="pending"), train)
    assert empty.empty and list(empty.columns) == list(out.columns)
    assert observed_rates(empty) == {}


def test_merged_rates__default_base_is_the_builtin_rates() -> None:
    out = merged_rates({"decentralized": {"train": {40: 9.0}}})
    assert out["decentralized"]["train"] == {40: 9.0}
    assert out["ic3net"] == costs.AGENT_STEPS_PER_S["ic3net"]


def test_builtin_rates__are_the_committed_reproductions(reproduction: pd.DataFrame) -> None:
    """The built-in rates are what the committed run they name observed (the paper grid, or
    the full grid once it has finished). Rebuild with `scripts/calibrate_costs.py RUN --write`
    when that run's state is committed."""
    builtin = json.loads(costs.RATES_FILE.read_text())
    assert builtin["run"] in ("reproduction/paper", "reproduction/full")
    root = REPRODUCTION.parent.parent
    copied = () if builtin["copied_from"] is None else \
        pd.read_parquet(root / builtin["copied_from"] / "cells.parquet")["cell_id"]
    source = observed_costs(root / builtin["run"], builtin["stack_seeds"], copied)
    assert builtin == rates_file(source, builtin["run"], builtin["stack_seeds"], builtin["copied_from"])
    for method, phases in observed_rates(source).items():
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
    assert out == {"run": "runs/x", "stack_seeds": 1, "copied_from": None, "done_cells": 3,
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


def test_estimate_vs_realized__per_method_with_the_runs_stacks_and_without_excluded_cells() -> None:
    """Two done hierarchical seeds of one configuration (a stack of 3 with the third,
    pending), one done decentralized cell, one copied-in cell left out: estimates at the
    stack size the run formed, realized = the cells' wall_s, ratios, and a total row."""
    grid = get_grid("paper").cells
    h = _hierarchical_seeds(grid)
    d0, d1 = [c for c in grid if c.method == "decentralized"][:2]
    cells = pd.DataFrame([dict(cell_id=c.cell_id, status=s, wall_s=w, config_json=c.canonical_json())
                          for c, s, w in ((h[0], "done", 3600.0), (h[1], "done", 7200.0), (h[2], "pending", 0.0),
                                          (d0, "done", 1800.0), (d1, "done", 99.0))])
    out = estimate_vs_realized(cells, stack_seeds=3, exclude=[d1.cell_id]).set_index("method")
    assert list(out.index) == ["decentralized", "hierarchical", "all"]
    assert list(out["cells"]) == [1, 2, 3]
    est_h = (costs.cell_seconds(h[0], None, 3) + costs.cell_seconds(h[1], None, 3)) / 3600
    est_d = costs.cell_seconds(d0) / 3600
    assert costs.cell_seconds(h[0], None, 3) < costs.cell_seconds(h[0])  # the stack is what is charged
    assert out.loc["hierarchical", "estimated_h"] == pytest.approx(est_h)
    assert out.loc["hierarchical", "realized_h"] == pytest.approx(3.0)
    assert out.loc["decentralized", "realized_h"] == pytest.approx(0.5)  # d1 is left out
    assert out.loc["all", "estimated_h"] == pytest.approx(est_h + est_d)
    assert out.loc["all", "ratio"] == pytest.approx(3.5 / (est_h + est_d))
    unstacked = estimate_vs_realized(cells, stack_seeds=1).set_index("method")
    assert unstacked.loc["hierarchical", "estimated_h"] == pytest.approx(
        (costs.cell_seconds(h[0]) + costs.cell_seconds(h[1])) / 3600)
    assert unstacked.loc["decentralized", "cells"] == 2


def test_estimate_vs_realized__given_rates_unstacked_by_default_and_no_ratio_for_a_free_estimate() -> None:
    """The rates passed are the ones charged, the default is no stacking, a method
    estimated at 0 s has no ratio (not inf), the rows are numbered 0..k, and a run with
    no done cell gives the total row alone."""
    grid = get_grid("paper").cells
    h = _hierarchical_seeds(grid)
    p = next(c for c in grid if c.method == "pibt")
    cells = pd.DataFrame([dict(cell_id=c.cell_id, status="done", wall_s=60.0, config_json=c.canonical_json())
                          for c in (*h, p)])
    rates = {"hierarchical": {"train": {40: 1_000.0}, "eval": {40: 2_000.0}},
             "pibt": {"train": {20: float("inf")}, "eval": {20: float("inf")}}}
    out = estimate_vs_realized(cells, rates=rates)
    assert list(out.index) == [0, 1, 2] and list(out["method"]) == ["hierarchical", "pibt", "all"]
    train, ev = costs.cell_agent_steps(h[0])
    assert out["estimated_h"][0] == pytest.approx(3 * (train / 1_000.0 + ev / 2_000.0) / 3600)
    assert out["estimated_h"][1] == 0.0 and np.isnan(out["ratio"][1])
    assert out["ratio"][0] == pytest.approx(out["realized_h"][0] / out["estimated_h"][0])
    none_done = estimate_vs_realized(cells.assign(status="pending"))
    assert list(none_done["method"]) == ["all"] and list(none_done["cells"]) == [0]
    assert list(none_done.index) == [0] and np.isnan(none_done["ratio"][0])


def test_run_stacks__runs_that_recorded_no_stacks_stacked_per_group_hierarchical_cells_only() -> None:
    """A run made before decision 0237 with --stack-seeds 3 stacked the per-group hierarchical
    method only: its decentralized, IC3Net and shared-parameter cells are read as trained
    alone, although all three stack today."""
    from bench.design import cost_calibration
    from bench.design.cells import Cell

    grid = get_grid("paper").cells
    h = _hierarchical_seeds(grid)
    d, ic3 = ([c for c in grid if c.method == name and c.n_robots == 40 and c.loss_p == 0.2][:3]
              for name in ("decentralized", "ic3net"))
    shared = [Cell.make(**{**json.loads(c.canonical_json()), "params": {"share_params": True}}) for c in h]
    every = [*h, *d, *ic3, *shared]
    assert all(c.stackable() for c in every)
    cells = pd.DataFrame([dict(cell_id=c.cell_id, config_json=c.canonical_json()) for c in every])
    stacks = cost_calibration.run_stacks(cells, every, 3)
    assert [stacks[c.cell_id] for c in every] == [3] * 3 + [1] * 9
