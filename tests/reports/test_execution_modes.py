"""Reports with every execution mode: the summary has a row per configuration and mode,
Table I a block per mode, Fig. 2 a row of panels per mode and N, each from that mode's
rows only (never pooled)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from paper.figures.fig2_success import fig2_modes, fig2_success
from paper.tables.table1_safety import table1_frame, table1_latex, table1_markdown
from reports.data.store import execution_order, fmt_pct
from reports.tables.summary import fmt_ci, summary_frame, summary_markdown
from tests.reports.synthetic import frames, joined

MODES = ["argmax", "sample", "sample@0.5"]
SHIFT = {"argmax": 0.0, "sample": -0.3, "sample@0.5": -0.1}  # success offset per mode


@pytest.fixture(scope="module")
def store() -> tuple[pd.DataFrame, pd.DataFrame]:
    """(cells, eval rows in three modes with success shifted per mode) of a synthetic run."""
    cells, _, evals = frames(seeds=2, episodes=4, eval_eps=10)
    learned = evals[evals["execution"] == "argmax"]
    parts = [evals[evals["execution"] != "argmax"]]
    for mode in MODES:
        part = learned.copy()
        part["execution"] = mode
        part["success_rate"] = (part["success_rate"] + SHIFT[mode]).clip(0, 1)
        part["correction_rate"] = part["correction_rate"] * (1 + 2 * (mode != "argmax"))
        parts.append(part)
    return cells, joined(cells, pd.concat(parts, ignore_index=True))


def test_execution_order__argmax_sample_then_tempered_by_decreasing_t_then_planner() -> None:
    assert execution_order(["planner", "sample@0.25", "sample", "sample@0.5", "argmax", "sample"]) == [
        "argmax", "sample", "sample@0.5", "sample@0.25", "planner"]


def test_summary__one_row_per_configuration_and_mode_from_that_mode_only(store) -> None:
    cells, ev = store
    s = summary_frame(ev, cells)
    hier = s[(s["method"] == "hierarchical") & (s["n_robots"] == 40) & (s["loss_p"] == 0.2)]
    assert hier["execution"].tolist() == MODES
    rows = ev[(ev["method"] == "hierarchical") & (ev["n_robots"] == 40) & np.isclose(ev["loss_p"], 0.2)]
    for mode in MODES:
        want = rows[rows["execution"] == mode].groupby("cell_id")["success_rate"].mean().mean()
        got = hier.loc[hier["execution"] == mode, "success_rate"].item()
        assert got == pytest.approx(want)
        assert hier.loc[hier["execution"] == mode, "eval_episodes"].item() == 2 * 10
    assert len(set(hier["success_rate"].round(6))) == 3
    assert (s["execution"] != "-").all() and len(s) == (18 + 3 + 6) * 3
    assert "| hierarchical | 40 | 0.2 | sample@0.5 |" in summary_markdown(s)


def test_table1__a_block_per_mode_with_that_modes_numbers(store) -> None:
    _, ev = store
    t1, _ = table1_frame(ev)
    assert t1["execution"].tolist() == [m for m in MODES for _ in range(6)]
    corr = t1.set_index(["execution", "n_robots"])["correction_rate"]
    assert corr[("sample", 40)] == pytest.approx(3 * corr[("argmax", 40)])
    md, tex = table1_markdown(t1, []), table1_latex(t1)
    assert [line for line in md.splitlines() if line.startswith("## ")] == [f"## Execution: {m}" for m in MODES]
    assert tex.count(r"\begin{tabular}") == 3 and "tab:safety_reproduced_sample_0_5" in tex


def test_fig2__a_figure_per_mode_with_the_papers_six_panels(store) -> None:
    _, ev = store
    assert fig2_modes(ev) == MODES
    built = {m: fig2_success(ev, m) for m in MODES}
    for m, b in built.items():
        titles = [ax.get_title() for ax in b.fig.axes if ax.get_title()]
        assert titles == [f"N = {n}, p = {p}" for n in (40, 60) for p in (0.2, 0.4, 0.6)]
        assert b.caption.startswith(f"Fig. 2 ({m} execution)")
    assert fig2_success(ev).caption == built["argmax"].caption  # the default is the first mode
    # the argmax and sample figures draw different curves (each from its own mode's rows)
    ax0, ax_s = built["argmax"].fig.axes[0], built["sample"].fig.axes[0]
    assert not np.allclose(ax0.lines[0].get_ydata(), ax_s.lines[0].get_ydata())


def test_table1__a_tiny_collision_rate_is_not_printed_as_the_papers_zero(store) -> None:
    """N = 80 argmax of the reproduction read "0.00%" beside the paper's 0.00% while 35 of
    300 episodes collided: collision rates get three significant digits, zero stays 0.00."""
    _, ev = store
    ev = ev.copy()
    hier = (ev["method"] == "hierarchical") & np.isclose(ev["loss_p"], 0.2) & (ev["execution"] == "argmax")
    ev.loc[hier, "collision_rate"] = 0.0
    ev.loc[hier & (ev["n_robots"] == 40), "collision_rate"] = 7.61e-6
    t1, _ = table1_frame(ev)
    md = table1_markdown(t1, [])
    rows = {line.split(" | ")[0]: line.split(" | ") for line in md.split("## Execution: sample")[0].splitlines()
            if line.startswith("| 40 |") or line.startswith("| 60 |")}
    assert rows["| 40"][1:3] == ["0.000761% [0.000761, 0.000761]", "0.00%"]
    assert rows["| 60"][1] == "0.00% [0.00, 0.00]"
    tex_rows = [line for line in table1_latex(t1).splitlines() if line.startswith("40 & ours")]
    assert tex_rows[0].split(" & ")[2] == "0.000761" and tex_rows[1].split(" & ")[2] == "0.00"


def test_fmt_pct__a_nonzero_rate_never_prints_as_zero() -> None:
    """The summary and the ablation table show rates with one decimal and Table I with two;
    a nonzero rate those decimals would hide gets three significant digits instead."""
    assert [fmt_pct(x, 1) for x in (0.0, 0.843, 0.105, 1.0)] == ["0.0", "84.3", "10.5", "100.0"]
    assert [fmt_pct(x, 1) for x in (4.15e-5, 4e-4, 1.23e-9)] == ["0.00415", "0.04", "0.000000123"]
    assert fmt_pct(0.0345, 2, always_sig=True) == "3.45" and fmt_pct(0.0, 2, always_sig=True) == "0.00"
    assert fmt_ci(4.15e-5, 0.0, 1.8e-4, "pct") == "0.00415% [0.0%, 0.018%]"
