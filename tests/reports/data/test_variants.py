"""reports/data/variants.py: cells of one (method, N, p) that differ in more than their seed are
variants, never pooled as seeds: each has its own summary and success-table row, and the
figures, Table I and the claims use the default variant only."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from reports.build import build_report
from reports.data.variants import MERGED, cell_variants, default_rows
from reports.tables.success_table import success_frame
from reports.tables.summary import summary_frame
from tests.reports.synthetic import frames, write_store


def _cells(rows: list[tuple[str, str, int, dict, dict]]) -> pd.DataFrame:
    """(cell_id, method, N, params, extra config) -> cells with resolved params and config."""
    return pd.DataFrame([{
        "cell_id": cid, "method": method, "n_robots": n, "loss_p": 0.2,
        "params_json": json.dumps(params),
        "config_json": json.dumps({"method": method, "n_robots": n, "loss_p": 0.2, "seed": k,
                                   "episodes": 100, "params": params, **extra}),
    } for k, (cid, method, n, params, extra) in enumerate(rows)])


def test_cell_variants__label_only_what_varies_and_only_where_it_departs_from_the_default() -> None:
    cells = _cells([
        ("a0", "hierarchical", 40, {"messages": "predicted", "ref_hold": 1}, {}),
        ("a1", "hierarchical", 40, {"messages": "predicted", "ref_hold": 1}, {}),  # another seed
        ("b0", "hierarchical", 40, {"messages": "oracle", "ref_hold": 1}, {}),
        ("c0", "hierarchical", 40, {"messages": "predicted", "ref_hold": 10}, {}),
        ("d0", "hierarchical", 60, {"messages": "oracle"}, {}),  # alone in its group: the default
        ("e0", "decentralized", 40, {}, {"episodes": 100}),
        ("e1", "decentralized", 40, {}, {"episodes": 200}),  # not a hyperparameter: always named
    ])
    v = cell_variants(cells)
    assert v.to_dict() == {"a0": "", "a1": "", "b0": "messages=oracle", "c0": "ref_hold=10", "d0": "",
                           "e0": "episodes=100", "e1": "episodes=200"}
    kept = default_rows(cells, v)
    assert sorted(kept["cell_id"]) == ["a0", "a1", "d0"]


def test_cell_variants__a_report_against_a_reference_headlines_the_run_s_own_cells() -> None:
    """``bench report --against REF``: where the run re-ran a method of REF with other
    settings, the run's cells are the default variant and REF's are labelled; a group the
    run does not hold keeps REF's cells as its default; the run's own variants stay labelled
    relative to what the run's cells share."""
    cells = _cells([
        ("m0", "hierarchical", 40, {"protocol": "mappo"}, {}),
        ("m1", "hierarchical", 40, {"protocol": "mappo"}, {}),
        ("r0", "hierarchical", 40, {}, {}),  # REF at the paper protocol (the method's default)
        ("d0", "decentralized", 40, {"protocol": "mappo", "ref": 1}, {}),
        ("d1", "decentralized", 40, {"protocol": "mappo", "ref": 2}, {}),  # the run's own two variants
        ("s0", "decentralized", 40, {}, {}),
        ("p0", "pibt", 40, {}, {}),  # only REF has it
    ]).assign(**{MERGED: [False, False, True, False, False, True, True]})
    v = cell_variants(cells).to_dict()
    assert v == {"m0": "", "m1": "", "r0": "protocol=paper", "d0": "ref=1", "d1": "ref=2",
                 "s0": "protocol=paper, ref=None", "p0": ""}
    assert sorted(default_rows(cells, cell_variants(cells))["cell_id"]) == ["m0", "m1", "p0"]
    alone = cells.drop(columns=[MERGED])  # the same cells in one run: labelled against the defaults
    assert cell_variants(alone).to_dict()["r0"] == "" and cell_variants(alone).to_dict()["m0"] == "protocol=mappo"


def test_cell_variants__a_store_without_settings_is_one_variant_per_group() -> None:
    cells = pd.DataFrame({"cell_id": ["x", "y"], "method": ["ic3net"] * 2, "n_robots": [40, 40],
                          "loss_p": [0.2, 0.2]})
    assert cell_variants(cells).to_dict() == {"x": "", "y": ""}
    for params_json, config_json in (("", None), (None, "")):  # empty JSON columns: nothing stored
        empty = cells.assign(params_json=params_json, config_json=config_json)
        assert cell_variants(empty).to_dict() == {"x": "", "y": ""}


def test_cell_variants__names_every_departing_key_and_a_setting_a_cell_lacks() -> None:
    cells = _cells([("a", "hierarchical", 40, {}, {}),
                    ("b", "hierarchical", 40, {"messages": "oracle", "ref_hold": 10}, {})])
    assert cell_variants(cells).to_dict() == {"a": "", "b": "messages=oracle, ref_hold=10"}
    no_budget = cells.assign(config_json=[json.dumps({"seed": 0}), json.dumps({"seed": 1, "episodes": 50})])
    assert cell_variants(no_budget).to_dict() == {"a": "episodes=None", "b": "episodes=50, messages=oracle, "
                                                                             "ref_hold=10"}


def test_cell_variants__the_same_nested_setting_written_in_another_key_order_is_one_variant() -> None:
    cells = _cells([("x", "pibt", 40, {"schedule": {"a": 1, "b": 2}}, {}),
                    ("y", "pibt", 40, {"schedule": {"b": 2, "a": 1}}, {}),
                    ("z", "pibt", 40, {"schedule": {"a": 1, "b": 3}}, {})])
    assert cell_variants(cells).to_dict() == {"x": "schedule={'a': 1, 'b': 2}", "y": "schedule={'a': 1, 'b': 2}",
                                              "z": "schedule={'a': 1, 'b': 3}"}


def test_default_rows__keeps_rows_of_unlabelled_cells_and_tables_without_cell_ids() -> None:
    variants = pd.Series({"a": "", "b": "messages=oracle"})
    rows = pd.DataFrame({"cell_id": ["a", "b", "c"], "v": [1, 2, 3]})
    assert list(default_rows(rows, variants)["v"]) == [1, 3]  # c is in no variant table: kept
    plain = pd.DataFrame({"v": [1, 2]})
    assert default_rows(plain, variants) is plain


def _two_variant_evals() -> tuple[pd.DataFrame, pd.DataFrame]:
    """Three seeds at success 0.9 (default) and three at 0.1 (messages=oracle), N = 40."""
    cells = _cells([(f"p{s}", "hierarchical", 40, {"messages": "predicted"}, {}) for s in range(3)]
                   + [(f"o{s}", "hierarchical", 40, {"messages": "oracle"}, {}) for s in range(3)])
    cells = cells.assign(status="done", safety_filter=True, executions="argmax")
    evals = pd.DataFrame([{
        "cell_id": cid, "method": "hierarchical", "n_robots": 40, "loss_p": 0.2, "execution": "argmax",
        "episode": e, "success_rate": (0.9 if cid.startswith("p") else 0.1) + 0.01 * int(cid[1]),
        "team_return": 1.0, "collision_rate": 0.0, "correction_rate": 0.0, "payload_scalars_per_step": 0.0,
        "safety_filter": True} for cid in cells["cell_id"] for e in range(4)])
    return evals, cells


def test_summary_and_success_table__give_each_variant_its_own_row_with_its_own_seeds() -> None:
    evals, cells = _two_variant_evals()
    summary = summary_frame(evals, cells)
    assert list(summary["variant"]) == ["", "messages=oracle"]
    assert list(summary["seeds"]) == [3, 3]  # pooled, one row of 6 "seeds" at 0.5
    assert np.allclose(summary["success_rate"], [0.91, 0.11])
    table = success_frame(summary, cells)
    assert list(table["method"]) == ["Hierarchical (ours)", "Hierarchical (ours) [messages=oracle]"]
    assert list(table["seeds"]) == ["3/3", "3/3"]
    assert table["argmax"].iloc[0].startswith("91.0% [")


@pytest.fixture(scope="module")
def with_and_without_variant(tmp_path_factory):
    """The same synthetic paper store built twice, the second with three more hierarchical
    cells at N = 40, p = 0.2 (messages="oracle") whose training and evaluation are far
    worse: pooled as seeds they would flip the claims there."""
    cells, train, evals = frames(seeds=3, episodes=60, eval_eps=10)
    plain = build_report(write_store(tmp_path_factory.mktemp("plain"), cells, train, evals))
    base = cells[(cells["method"] == "hierarchical") & (cells["n_robots"] == 40) & (cells["loss_p"] == 0.2)]
    ids = {cid: f"v{cid[1:]}" for cid in base["cell_id"]}
    extra = base.assign(cell_id=base["cell_id"].map(ids), params_json=json.dumps({"messages": "oracle"}))
    t = train[train["cell_id"].isin(ids)].assign(cell_id=lambda d: d["cell_id"].map(ids))
    e = evals[evals["cell_id"].isin(ids)].assign(cell_id=lambda d: d["cell_id"].map(ids))
    t, e = t.assign(team_return=t["team_return"] - 50.0), e.assign(success_rate=0.0, team_return=0.0)
    mixed = build_report(write_store(tmp_path_factory.mktemp("mixed"), pd.concat([cells, extra]),
                                     pd.concat([train, t]), pd.concat([evals, e])))
    return plain, mixed


def test_build_report__claims_figures_and_table1_ignore_a_variant(with_and_without_variant) -> None:
    plain, mixed = with_and_without_variant
    for name in ("claims.csv", "claims_table.md", "table1_safety.md", "fig1_training.txt",
                 "fig2_success_percentiles.txt"):
        assert (mixed / name).read_text() == (plain / name).read_text(), name


def test_build_report__the_variant_has_its_own_summary_row_and_the_index_says_so(with_and_without_variant) -> None:
    plain, mixed = with_and_without_variant
    table = (mixed / "success_by_mode.md").read_text()
    assert "| 40 | 0.2 | Hierarchical (ours) [messages=oracle] | 3/3 | 0.0% [0.0%, 0.0%] (fallback " in table
    assert "[messages=oracle]" not in (plain / "success_by_mode.md").read_text()
    assert "3 cells are variants of their configuration" in (mixed / "index.md").read_text()


def test_cell_variants__a_lifelong_cell_is_its_task_s_default_not_a_variant_of_the_one_shot_cell() -> None:
    cells = _cells([("s0", "pibt", 40, {}, {}), ("s1", "pibt", 40, {}, {}),  # one-shot (the default task)
                    ("l0", "pibt", 40, {}, {"task": "lifelong"}), ("l1", "pibt", 40, {}, {"task": "lifelong"}),
                    ("d0", "pibt", 40, {}, {"task": "lifelong", "delay": 2})])
    v = cell_variants(cells)
    assert v.to_dict() == {"s0": "", "s1": "", "l0": "", "l1": "", "d0": "delay=2"}  # not "task=lifelong"
    assert sorted(default_rows(cells, v)["cell_id"]) == ["l0", "l1", "s0", "s1"]  # both tasks reach the leaderboard
