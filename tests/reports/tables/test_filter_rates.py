"""Fallback and correction rates beside every score of a method that runs a safety filter (the
hierarchical method; issue 47 item 3, docs/decisions/0236): in the leaderboard (its page and the
index's table), the success table and the summary; a method without a filter shows none."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from reports.tables.leaderboard import (
    aggregate_frame,
    leaderboard_display,
    leaderboard_frame,
    leaderboard_markdown,
    safety_frame,
)
from reports.tables.summary import FILTER_NOTE, filter_text, summary_display, summary_frame


def _evals() -> pd.DataFrame:
    """Hierarchical (a filter) and decentralized (none) at N = 4, p = 0.2, argmax, 2 seeds x 2 episodes."""
    rows = []
    for method, filt in (("hierarchical", True), ("decentralized", False)):
        for seed in range(2):
            for ep in range(2):
                rows.append(dict(cell_id=f"{method}{seed}", method=method, n_robots=4, loss_p=0.2,
                                 execution="argmax", seed=seed, episode=ep, success_rate=0.5 + 0.1 * seed,
                                 team_return=1.0, collision_rate=0.0,
                                 # hierarchical: seed means 0.35 and 0.55 (corrections), 0.2 and 0.4 (fallback)
                                 correction_rate=(0.3 + 0.2 * seed + 0.1 * ep) if filt else 0.0,
                                 fallback_rate=(0.1 + 0.2 * seed + 0.2 * ep) if filt else np.nan,
                                 mean_candidates=3.0 if filt else np.nan, payload_scalars_per_step=1.0,
                                 safety_filter=filt))
    return pd.DataFrame(rows)


def test_filter_text__both_rates_or_nothing() -> None:
    assert filter_text(0.166, 0.0193) == " (fallback 1.9%, corrections 16.6%)"
    assert filter_text(np.nan, np.nan) == ""
    assert filter_text(0.0, np.nan) == " (fallback —, corrections 0.0%)"


def test_leaderboard__the_filtered_method_s_rates_beside_its_success_and_none_for_the_other() -> None:
    ev = _evals()
    board = leaderboard_frame(ev).set_index("method")
    assert board.loc["hierarchical", "correction_rate"] == pytest.approx(0.45)
    assert board.loc["hierarchical", "fallback_rate"] == pytest.approx(0.3)
    assert np.isnan(board.loc["decentralized", "correction_rate"])  # 0 corrections without a filter: none shown
    assert np.isnan(board.loc["decentralized", "fallback_rate"])
    board = leaderboard_frame(ev)
    iqm, poi = aggregate_frame(ev)
    md = leaderboard_markdown(board, iqm, poi, safety_frame(ev))
    hier = next(line for line in md.splitlines() if line.startswith("| 4 | 0.2 | argmax | Hierarchical"))
    # rank 1: tied with decentralized
    assert "(coverage" in hier and hier.endswith(" (fallback 30.0%, corrections 45.0%) | 1 |")
    dec = next(line for line in md.splitlines() if line.startswith("| 4 | 0.2 | argmax | Decentralized"))
    assert "fallback" not in dec and FILTER_NOTE in md
    shown = leaderboard_display(board).iloc[0]
    assert shown["Hierarchical (ours)"].endswith("(1) (fallback 30.0%, corrections 45.0%)")
    assert "fallback" not in shown["Decentralized"]


def test_summary__a_fallback_rate_column_beside_the_correction_rate() -> None:
    ev = _evals()
    cells = ev.drop_duplicates("cell_id")[["cell_id", "method", "n_robots", "loss_p", "safety_filter"]].assign(
        status="done", seed=[0, 1, 0, 1])
    summary = summary_frame(ev, cells).set_index("method")
    assert summary.loc["hierarchical", "fallback_rate"] == pytest.approx(0.3)
    shown = summary_display(summary_frame(ev, cells)).set_index("method")
    assert shown.loc["hierarchical", "fallback rate"].startswith("30.0% [")
    assert shown.loc["decentralized", "fallback rate"] == "n/a"


def test_filter_text__one_decimal_and_a_floor_for_tiny_rates() -> None:
    assert filter_text(0.000425, 0.000425) == " (fallback <0.1%, corrections <0.1%)"  # was "0.0425%"
    assert filter_text(0.0, 0.0006) == " (fallback 0.1%, corrections 0.0%)"
    assert filter_text(0.1234, 0.98765) == " (fallback 98.8%, corrections 12.3%)"
