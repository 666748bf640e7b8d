"""reports/tables/progress.py: the run's status per method, which the README shows for the
committed reproduction."""
from __future__ import annotations

import pandas as pd

from reports.tables.progress import progress_frame, progress_markdown


def _cells() -> pd.DataFrame:
    return pd.DataFrame({
        "method": ["hierarchical", "hierarchical", "ic3net", "ic3net", "pibt"],
        "status": ["done", "running", "done", "failed", "pending"],
        "wall_s": [3600.0, 1800.0, 900.0, float("nan"), 0.0],
        "n_robots": [40, 40, 40, 60, 20], "loss_p": [0.2, 0.4, 0.2, 0.2, 0.2], "seed": [0, 1, 0, 0, 2],
        "train_episodes_done": [2000, 1360, 2000, 80, 0], "episodes": [2000, 2000, 2000, 2000, 0],
    })


def test_progress__counts_per_method_in_stored_order_and_worker_hours() -> None:
    f = progress_frame(_cells())
    assert f["method"].tolist() == ["hierarchical", "ic3net", "pibt"]
    assert f[["done", "running", "pending", "failed", "cells"]].values.tolist() == [
        [1, 1, 0, 0, 2], [1, 0, 0, 1, 2], [0, 0, 1, 0, 1]]
    assert f["worker_hours"].tolist() == [1.5, 0.25, 0.0]  # a failed cell without wall time counts 0


def test_progress__markdown_has_a_total_row_and_names_the_cells_in_progress() -> None:
    md = progress_markdown(_cells())
    assert "| hierarchical | 1 | 1 | 0 | 0 | 2 | 1.5 |" in md
    assert "| all | 2 | 1 | 1 | 1 | 5 | 1.8 |" in md
    assert md.endswith("In progress: hierarchical N = 40, p = 0.4, seed 1 at 1,360 of 2,000 training episodes.\n")
    done = _cells().assign(status="done")
    assert "In progress" not in progress_markdown(done)
