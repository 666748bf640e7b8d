"""Cell fields added after the first committed stores (delay, delay_model, task) keep every
old cell id while at their default, and change it when set."""
from __future__ import annotations

import json

import pytest

from bench.design.cells import LATER_FIELDS, Cell
from envs.errors import BenchError


def test_later_fields__absent_from_the_id_at_their_default():
    cell = Cell.make(method="pibt", n_robots=8, loss_p=0.2)
    data = json.loads(cell.canonical_json())
    assert not set(LATER_FIELDS) & set(data)
    assert cell.cell_id == "72b0b05bf7c4"  # the id this config had before the fields existed


@pytest.mark.parametrize("extra", [{"delay": 2}, {"delay": 1.5, "delay_model": "geometric"},
                                   {"task": "lifelong", "delay": 0}])
def test_later_fields__set_one_and_the_id_changes(extra):
    plain = Cell.make(method="pibt", n_robots=8, loss_p=0.2)
    cell = Cell.make(method="pibt", n_robots=8, loss_p=0.2, **extra)
    assert cell.cell_id != plain.cell_id
    env = cell.to_env_config()
    assert env.delay == extra["delay"] and env.delay_model == extra.get("delay_model", "fixed")
    assert env.task == extra.get("task", "one-shot")


def test_delay__bad_values_are_one_clear_error():
    with pytest.raises(BenchError, match="delay.*whole number"):
        Cell.make(method="pibt", n_robots=8, loss_p=0.2, delay=2.5)
    with pytest.raises(BenchError, match="delay"):
        Cell.make(method="pibt", n_robots=8, loss_p=0.2, delay=-1)


def test_lifelong_grid__every_method_lifelong_with_and_without_delay():
    from bench.design.grids import ALL_METHODS, get_grid

    grid = get_grid("lifelong")
    assert {c.method for c in grid.cells} == set(ALL_METHODS)
    assert {c.task for c in grid.cells} == {"lifelong"}
    assert {c.delay for c in grid.cells} == {0.0, 2.0}
    assert all(c.episodes == 0 for c in grid.cells if c.method == "pibt")
