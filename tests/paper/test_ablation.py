"""The ablation report section: variant matching, the table and the component sentences.

A tiny ablation grid (8 robots on `tiny`, 4 training episodes, 2 seeds) is trained and
evaluated in this process with the runner's store calls, then ``bench report``'s builder
runs on it. Runtime: about 20 s.
"""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from bench.design.grids import Grid, replicate
from paper.grids import ABLATION_VARIANTS, ablation, ablation_specs
from paper.tables.ablation import ablation_frame, ablation_markdown, component_values, variant_of
from reports.build import build_report
from tests.bench.conftest import write_finished_store

LABELS = [v.label for v in ABLATION_VARIANTS]


def test_ablation_grid__variants_seeds_and_the_issue_settings() -> None:
    g = ablation()
    assert len(g) == 3 * len(ABLATION_VARIANTS)
    assert {(c.n_robots, c.loss_p, c.episodes, c.horizon) for c in g.cells} == {(40, 0.2, 1000, 300)}
    assert {c.layout for c in g.cells} == {"warehouse-10-20-10-2-1"}
    assert set(g.methods) == {"hierarchical", "decentralized"}
    found = [variant_of(c.method, c.ref_size, json.dumps(c.params)) for c in g.cells]
    assert [v.label for v in found if v] == [label for label in LABELS for _ in range(3)]
    assert len(set(LABELS)) == len(LABELS)


def test_variant_of__ignores_non_defining_params_and_needs_the_method_and_ref_size() -> None:
    assert variant_of("hierarchical", 8, json.dumps({"batch_episodes": 2})).label == "paper"
    assert variant_of("hierarchical", 1, "{}").label == "no reference"
    assert variant_of("hierarchical", 8, json.dumps({"messages": "oracle"})).label == "oracle messages"
    assert variant_of("hierarchical", 8, json.dumps({"messages": "oracle", "share_params": True})) is None
    assert variant_of("ic3net", 8, "{}") is None


def synthetic(success: dict[str, list[float]]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """cells and eval rows: per variant one cell per listed seed value, 2 episodes each
    with success v - 0.1 and v + 0.1 (per-seed mean v)."""
    cells, evals = [], []
    by_label = {v.label: v for v in ABLATION_VARIANTS}
    for label, values in success.items():
        v = by_label[label]
        for s, val in enumerate(values):
            cid = f"{label}-{s}"
            cells.append({"cell_id": cid, "grid": "ablation", "method": v.method, "ref_size": v.ref_size,
                          "params_json": json.dumps(v.params), "n_robots": 40, "loss_p": 0.2,
                          "layout": "m", "episodes": 10, "horizon": 5, "eval_episodes": 2})
            for e, x in enumerate((val - 0.1, val + 0.1)):
                evals.append({"cell_id": cid, "episode": e, "success_rate": x, "collision_rate": 0.0,
                              "correction_rate": 0.1, "fallback_rate": 0.2, "payload_scalars_per_step": 90.0})
    return pd.DataFrame(evals), pd.DataFrame(cells)


def test_ablation_frame_and_components__numbers_worked_by_hand() -> None:
    evals, cells = synthetic({"paper": [0.5, 0.6, 0.7], "last-received messages": [0.2, 0.3, 0.4],
                              "no reference": [0.6]})
    frame = ablation_frame(evals, cells)
    assert frame["variant"].tolist() == ["paper", "no reference", "last-received messages"]  # grid order
    paper = frame.set_index("variant").loc["paper"]
    assert paper["seeds"] == 3 and paper["eval_episodes"] == 6
    assert paper["success_rate"] == pytest.approx(0.6) and paper["ci_over"] == "seeds"
    # Student t over 3 seed means on the logit scale (a rate: inside [0, 1] by construction):
    # logit(0.5, 0.6, 0.7) = 0, 0.405, 0.847: 0.418 -+ t_{0.975, 2} (4.303) x 0.424 / sqrt(3), mapped back
    assert paper["success_rate_lo"] == pytest.approx(0.34635, abs=1e-4)
    assert paper["success_rate_hi"] == pytest.approx(0.81310, abs=1e-4)
    assert frame["execution"].unique().tolist() == ["argmax"]  # no column: one mode
    comps = {c["with"] + "|" + c["without"]: c for c in component_values(evals, cells)}
    gru = comps["paper|last-received messages"]
    assert gru["delta"] == pytest.approx(0.3) and gru["lo"] > 0 and gru["seeds"] == (3, 3)
    assert comps["paper|no reference"]["seeds"] == (3, 1)
    text = ablation_markdown(frame, list(comps.values()))
    assert "+30.0 points" in text and "worth it" in text
    assert "no verdict" in text  # the one-seed arm
    # Cells of other grids are never pooled in.
    other = cells.assign(grid="paper")
    assert ablation_frame(evals, other).empty


def test_bench_report__tiny_ablation_run_builds_the_section(tmp_path) -> None:
    specs = ablation_specs(n_robots=8, layout="tiny", episodes=4, horizon=12, eval_episodes=4,
                           params={"batch_episodes": 2, "eval_chunk": 2})
    grid = Grid("ablation", "tiny ablation", replicate(specs, 2))
    out = tmp_path / "run"
    write_finished_store(out, grid)
    report = build_report(out)
    text = (report / "ablation.md").read_text()
    for label in LABELS:
        assert f"| {label} | 2 | 8 |" in text, label
    table = pd.read_csv(report / "ablation.csv")
    modes = table["execution"].unique().tolist()
    assert modes == ["argmax", "sample", "sample@0.5"]  # one table per mode, never pooled
    assert text.count("points [") == 8 * len(modes)  # every component, with a CI over 2 vs 2 seeds
    assert text.count("no verdict") == 8 * len(modes)  # 2 seeds per arm: below the 3-seed rule
    assert "ablation.md" in (report / "index.md").read_text()
    page = (report / "index.html").read_text()  # rendered as HTML tables, one per mode
    assert all(f"<caption>Ablation, {m} execution" in page for m in modes)
    assert np.isfinite(table["success_rate"]).all() and (table["collision_rate"] >= 0).all()
