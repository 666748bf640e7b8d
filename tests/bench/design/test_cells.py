"""Cells: validation names the bad field, ids are stable hashes, params reach the method."""
from __future__ import annotations

import hashlib
import json

import pytest

from bench.design.cells import Cell
from envs.errors import BenchError


def test_cell__auto_layout_and_safety_filter_default_resolve_per_method() -> None:
    h = Cell.make(method="hierarchical", n_robots=40, loss_p=0.2)
    d = Cell.make(method="decentralized", n_robots=40, loss_p=0.2)
    assert h.layout == d.layout == "wh40"
    assert h.safety_filter is True and d.safety_filter is False
    assert Cell.make(method="decentralized", n_robots=40, loss_p=0.2, safety_filter=True).safety_filter


def test_cell__id_is_sha256_of_canonical_json_and_pinned() -> None:
    cell = Cell.make(method="pibt", n_robots=20, loss_p=0.2, seed=3)
    canonical = cell.canonical_json()
    assert cell.cell_id == hashlib.sha256(canonical.encode()).hexdigest()[:12]
    assert json.loads(canonical)["layout"] == "wh20"
    # Pinned: a change here silently orphans every stored result (bump SCHEMA_VERSION instead).
    assert canonical == (
        '{"c_max":500,"episodes":2000,"eval_episodes":100,"eval_temperatures":[0.5],"groups":4,'
        '"horizon":500,"layout":"wh20","loss_model":"bernoulli","loss_p":0.2,"method":"pibt",'
        '"n_robots":20,"on_goal":"remove","params":{},"ref_size":8,"safety_filter":false,'
        '"search_radius":2,"seed":3}'
    )
    assert cell.cell_id == "a933e94de172"


def test_cell__id_ignores_params_order_and_changes_with_any_field() -> None:
    a = Cell.make(method="hierarchical", n_robots=20, loss_p=0.2, params={"lr": 1e-3, "hidden": 32})
    b = Cell.make(method="hierarchical", n_robots=20, loss_p=0.2, params={"hidden": 32, "lr": 1e-3})
    assert a.cell_id == b.cell_id
    variants = [dict(seed=1), dict(loss_p=0.4), dict(n_robots=21), dict(search_radius=1),
                dict(c_max=100), dict(horizon=100), dict(params={"lr": 2e-3, "hidden": 32}),
                dict(loss_model="gilbert_elliott"), dict(safety_filter=False)]
    base = dict(method="hierarchical", n_robots=20, loss_p=0.2, params={"lr": 1e-3, "hidden": 32})
    ids = {Cell.make(**{**base, **v}).cell_id for v in variants}
    assert len(ids) == len(variants) and a.cell_id not in ids


def test_cell__json_round_trip_gives_the_same_cell() -> None:
    cell = Cell.make(method="ic3net", n_robots=8, loss_p=0.6, layout="tiny", params={"hidden": 16})
    again = Cell.from_json(cell.canonical_json())
    assert again == cell and again.cell_id == cell.cell_id


@pytest.mark.parametrize(("fields", "named"), [
    (dict(n_robots=0), "n_robots"),
    (dict(loss_p=1.5), "loss_p"),
    (dict(loss_p=0.9, loss_model="gilbert_elliott"), "loss_p"),  # bursts of 4 allow at most 0.8
    (dict(seed=-1), "seed"),
    (dict(method="qmix"), "method"),
    (dict(groups=30, n_robots=20), "groups"),
    (dict(c_max=0), "c_max"),
    (dict(horizon=0), "horizon"),
    (dict(eval_episodes=0), "eval_episodes"),
    (dict(on_goal="fly"), "on_goal"),
    (dict(colour="red"), "colour"),
    (dict(layout="nowhere"), "layout"),
    (dict(n_robots=60, layout="tiny"), "n_robots"),
    (dict(params={"ref_size": 4}), "params.ref_size"),
    (dict(params={"no_such_knob": 1}), "no_such_knob"),
    (dict(params={"lr": "fast"}), "lr"),
])
def test_cell__invalid_value_is_one_bench_error_naming_the_field(fields: dict, named: str) -> None:
    spec = dict(method="hierarchical", n_robots=20, loss_p=0.2)
    spec.update(fields)
    with pytest.raises(BenchError) as err:
        Cell.make(**spec)
    msg = str(err.value)
    assert named in msg and "\n" not in msg


def test_cell__method_params_merge_shared_fields_only_where_declared() -> None:
    h = Cell.make(method="hierarchical", n_robots=20, loss_p=0.2, ref_size=5, search_radius=1,
                  c_max=77, params={"lr": 5e-4})
    hp = h.method_params()
    assert (hp.ref_size, hp.search_radius, hp.c_max, hp.safety_filter, hp.lr) == (5, 1, 77, True, 5e-4)
    p = Cell.make(method="pibt", n_robots=20, loss_p=0.2, ref_size=5).method_params()
    assert not hasattr(p, "ref_size")
    d = Cell.make(method="decentralized", n_robots=20, loss_p=0.2, safety_filter=True).method_params()
    assert d.safety_filter is True


def test_cell__env_config_carries_the_cell_settings() -> None:
    env = Cell.make(method="pibt", n_robots=8, loss_p=0.4, layout="tiny", groups=2, horizon=33,
                    on_goal="stay", loss_model="gilbert_elliott").to_env_config()
    assert (env.n_robots, env.loss_p, env.layout, env.groups, env.horizon, env.on_goal, env.loss_model) == (
        8, 0.4, "tiny", 2, 33, "stay", "gilbert_elliott")


def test_cell__is_frozen() -> None:
    cell = Cell.make(method="pibt", n_robots=8, loss_p=0.2)
    with pytest.raises(Exception):  # noqa: B017 - pydantic's frozen-instance error
        cell.seed = 4  # type: ignore[misc]
