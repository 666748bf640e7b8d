"""reports/figures/training_diagnostics.py: drawn only for train rows that hold the diagnostics."""
from __future__ import annotations

import numpy as np
import pandas as pd

from algorithms.common.diagnostic_columns import DIAGNOSTIC_COLUMNS
from reports.figures.training_diagnostics import PANELS, training_diagnostics


def _train(with_diag: bool) -> pd.DataFrame:
    rows = []
    for method in ("decentralized", "hierarchical"):
        for ep in range(40):
            row = {"method": method, "episode": ep, "collision_rate": 0.01 * ep}
            for c in DIAGNOSTIC_COLUMNS:
                row[c] = float(ep) if with_diag and not (method == "decentralized" and c.endswith("_ref")) else np.nan
            rows.append(row)
    return pd.DataFrame(rows)


def test_no_figure_for_a_store_without_diagnostics() -> None:
    assert training_diagnostics(_train(False)) is None
    assert training_diagnostics(_train(False).drop(columns=list(DIAGNOSTIC_COLUMNS))) is None


def test_one_panel_per_diagnostic_with_a_line_per_method() -> None:
    built = training_diagnostics(_train(True))
    assert built is not None and "decentralized" in built.notes[0]
    axes = built.fig.axes
    assert len(axes) == 8 and not axes[-1].axison
    entropy = axes[0]
    assert len(entropy.get_lines()) == 3  # two methods, and the hierarchical reference dashed
    assert [ax.get_ylabel() for ax in axes[:len(PANELS)]] == [label for _, label, _ in PANELS]
    assert entropy.get_lines()[0].get_ydata()[-1] > entropy.get_lines()[0].get_ydata()[0]  # the rising values
