"""Grids: the paper grid is exactly the paper's configurations; smoke covers every method;
grid files cross axes; costs follow the documented formula."""
from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import pytest

from bench.design import costs
from bench.design.grid_files import load_grid_file
from bench.design.grids import get_grid
from envs.errors import BenchError

# Written out by hand from the paper (Sec. IV, Fig. 1-3, Table I), not from bench/design/grids.py.
FIG1 = {("hierarchical", n, 0.2) for n in (20, 40, 60, 80, 90, 100)} | {
    ("decentralized", n, 0.2) for n in (20, 40, 60)}
FIG2 = {(m, n, p) for m in ("hierarchical", "ic3net") for n in (40, 60) for p in (0.2, 0.4, 0.6)}
FIG3 = {(m, n, 0.2) for m in ("hierarchical", "decentralized") for n in (20, 40, 60, 80, 90, 100)}
TABLE1 = {("hierarchical", n, 0.2) for n in (40, 60, 80, 90, 100)}
PIBT = {("pibt", n, 0.2) for n in (20, 40, 60, 80, 90, 100)}


def test_paper_grid__is_exactly_the_figure_and_table_configurations() -> None:
    grid = get_grid("paper")
    got = [(c.method, c.n_robots, c.loss_p) for c in grid.cells if c.seed == 0]
    assert len(got) == len(set(got)), "duplicated configuration"
    assert set(got) == FIG1 | FIG2 | FIG3 | TABLE1 | PIBT
    assert len(grid) == 28 * 3 and grid.configurations == 28 and grid.seeds == 3


def test_paper_grid__uses_the_paper_settings() -> None:
    for c in get_grid("paper").cells:
        assert (c.groups, c.search_radius, c.c_max, c.horizon, c.eval_episodes) == (4, 2, 500, 500, 100)
        assert c.episodes == (0 if c.method == "pibt" else 2000)
        assert c.safety_filter == (c.method == "hierarchical")
        assert c.layout == "warehouse-10-20-10-2-1" and c.seed in (0, 1, 2)  # 3 seeds by default
        assert c.eval_temperatures == (0.5,)


def test_smoke_grid__every_method_two_team_sizes_two_loss_probabilities() -> None:
    grid = get_grid("smoke")
    assert set(grid.methods) == {"hierarchical", "decentralized", "ic3net", "pibt"}
    for m in grid.methods:
        cells = [c for c in grid.cells if c.method == m]
        assert len({c.n_robots for c in cells}) >= 2 and len({c.loss_p for c in cells}) >= 2
    assert max(c.episodes * c.horizon * c.n_robots for c in grid.cells) <= 20_000  # tiny budgets


def test_full_grid__crosses_methods_sizes_probabilities_and_seeds() -> None:
    grid = get_grid("full", seeds=2)
    assert len(grid) == 4 * 6 * 3 * 2
    counts = Counter((c.method, c.n_robots, c.loss_p) for c in grid.cells)
    assert set(counts.values()) == {2}
    assert {c.seed for c in grid.cells} == {0, 1}


def test_seeds_option__replicates_each_configuration_over_seeds_0_to_k() -> None:
    one, five = get_grid("paper", seeds=1), get_grid("paper", seeds=5)
    assert len(five) == 5 * len(one) and five.seeds == 5 and five.configurations == len(one)
    assert {c.seed for c in five.cells} == {0, 1, 2, 3, 4}
    assert len({c.cell_id for c in five.cells}) == len(five)
    assert [c.cell_id for c in get_grid("paper").cells] == [c.cell_id for c in get_grid("paper", seeds=3).cells]


def test_unknown_grid__is_a_bench_error() -> None:
    with pytest.raises(BenchError, match="unknown grid 'nope'"):
        get_grid("nope")


def test_cost__is_episodes_times_horizon_times_n_over_throughput() -> None:
    cell = get_grid("paper").cells[0]
    assert cell.n_robots == 20  # a measured point: no interpolation
    rate = {k: v[20] for k, v in costs.AGENT_STEPS_PER_S[cell.method].items()}
    modes = 3  # argmax, sample, sample@0.5: every evaluation episode runs once per mode
    expected = (2000 * 500 * cell.n_robots / rate["train"] + modes * 100 * 500 * cell.n_robots / rate["eval"])
    assert costs.cell_seconds(cell) == pytest.approx(expected)
    assert costs.grid_cell_hours([cell, cell]) == pytest.approx(2 * expected / 3600)
    pibt = next(c for c in get_grid("paper").cells if c.method == "pibt" and c.n_robots == 20)
    assert costs.cell_seconds(pibt) == pytest.approx(100 * 500 * 20 / costs.AGENT_STEPS_PER_S["pibt"]["eval"][20])


def test_grid_file__toml_base_crossed_with_axes_including_params(tmp_path: Path) -> None:
    path = tmp_path / "sweep.toml"
    path.write_text(
        'description = "radius sweep"\nseeds = 2\n'
        '[base]\nmethod = "hierarchical"\nn_robots = 8\nlayout = "tiny"\nepisodes = 4\n'
        '[base.params]\nbatch_episodes = 2\n'
        '[axes]\nloss_p = [0.2, 0.6]\nsearch_radius = [1, 2, 3]\n"params.lr" = [0.001, 0.0003]\n'
    )
    grid = load_grid_file(path)
    assert grid.name == "sweep" and len(grid) == 2 * 3 * 2 * 2
    assert {c.params["lr"] for c in grid.cells} == {0.001, 0.0003}
    assert all(c.params["batch_episodes"] == 2 for c in grid.cells)
    assert len(load_grid_file(path, seeds=1)) == 12  # --seeds wins over the file


def test_grid_file__yaml_gives_the_same_cells_as_toml(tmp_path: Path) -> None:
    (tmp_path / "g.toml").write_text('[base]\nmethod = "pibt"\nlayout = "tiny"\n[axes]\nn_robots = [4, 8]\nloss_p = '
                                     '[0.2]\n')
    (tmp_path / "g.yaml").write_text("base:\n  method: pibt\n  layout: tiny\naxes:\n  n_robots: [4, 8]\n  loss_p: "
                                     "[0.2]\n")
    assert [c.cell_id for c in load_grid_file(tmp_path / "g.toml").cells] == [
        c.cell_id for c in load_grid_file(tmp_path / "g.yaml").cells]


@pytest.mark.parametrize(("text", "named"), [
    ('[base]\nmethod = "qmix"\nn_robots = 8\nloss_p = 0.2\n', "method"),
    ('[base]\nmethod = "pibt"\nloss_p = 0.2\n[axes]\nn_robots = [8, -1]\n', "n_robots"),
    ('[base]\nmethod = "pibt"\nn_robots = 8\n', "loss_p"),
    ('[base]\nmethod = "pibt"\nn_robots = 8\nloss_p = 0.2\n[axes]\nseed = []\n', "axes.seed"),
    ('[bsae]\nmethod = "pibt"\n', "bsae"),
    ('[base\nmethod = "pibt"\n', "not valid TOML"),
])
def test_grid_file__mistakes_are_one_line_errors_naming_the_key(tmp_path: Path, text: str, named: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(BenchError) as err:
        load_grid_file(path)
    assert named in str(err.value) and "bad.toml" in str(err.value) and "\n" not in str(err.value)


def test_cost_rate__builtin_points_are_met_exactly_and_clamped_outside() -> None:
    pts = costs.AGENT_STEPS_PER_S["ic3net"]["train"]
    lo, hi = min(pts), max(pts)
    a, b = sorted(pts)[:2]  # adjacent built-in sizes: linear between them
    assert costs.rate("ic3net", "train", (a + b) / 2) == pytest.approx((pts[a] + pts[b]) / 2)
    assert all(costs.rate("ic3net", "train", n) == r for n, r in pts.items())
    assert costs.rate("ic3net", "train", lo) == pts[lo]
    assert costs.rate("ic3net", "train", 8) == pts[lo]
    assert costs.rate("ic3net", "train", 400) == pts[hi]


def test_cost_rate__piecewise_linear_between_measured_sizes_and_clamped_outside(monkeypatch) -> None:
    monkeypatch.setitem(costs.AGENT_STEPS_PER_S, "toy", {"train": {20: 100.0, 40: 300.0, 100: 600.0},
                                                        "eval": {20: 1.0, 100: 1.0}})
    assert costs.rate("toy", "train", 10) == 100.0
    assert costs.rate("toy", "train", 30) == pytest.approx(200.0)
    assert costs.rate("toy", "train", 40) == 300.0
    assert costs.rate("toy", "train", 70) == pytest.approx(450.0)
    assert costs.rate("toy", "train", 200) == 600.0
    assert costs.rate("toy", "eval", 50) == 1.0


def test_cost_rate__an_infinite_rate_stays_exact_at_and_between_its_points() -> None:
    """A planner trains at an infinite rate: a point met exactly must not interpolate
    towards an infinite neighbour (0 * inf is NaN), nor a constant segment (inf - inf)."""
    table = {"toy": {"train": {20: 100.0, 60: 300.0, 100: math.inf}, "eval": {20: 50.0, 100: math.inf}},
             "planner": {"train": {20: math.inf, 100: math.inf}, "eval": {20: 1.0}}}
    assert costs.rate("toy", "train", 60, table) == 300.0
    assert costs.rate("toy", "eval", 20, table) == 50.0
    assert costs.rate("toy", "train", 80, table) == math.inf
    assert costs.rate("planner", "train", 50, table) == math.inf


def test_cost_rate__uses_the_given_table_and_the_default_for_an_unknown_method() -> None:
    table = {"toy": {"train": {20: 7.0}, "eval": {20: 9.0}}}
    assert costs.rate("toy", "train", 40, table) == 7.0
    assert costs.rate("hierarchical", "train", 40, table) == costs.DEFAULT_RATE["train"][20]
    assert costs.rate("no-such-method", "eval", 40) == costs.DEFAULT_RATE["eval"][20]


def test_cell_and_grid_cost__are_agent_steps_over_the_given_rates() -> None:
    grid = get_grid("paper").cells
    cells = [c for c in grid if c.method == "decentralized"][:2] + [c for c in grid if c.method == "pibt"][:2]
    table = {m: {"train": {20: r, 100: r}, "eval": {20: 2 * r, 100: 2 * r}}
             for m, r in (("decentralized", 1_000.0), ("pibt", math.inf))}
    expected = []
    for c in cells:
        train, ev = costs.cell_agent_steps(c)
        expected.append((train / table[c.method]["train"][20]) + ev / table[c.method]["eval"][20])
        assert costs.cell_seconds(c, table) == pytest.approx(expected[-1])
    assert costs.grid_cell_hours(cells, table) == pytest.approx(sum(expected) / 3600)
