"""How far a run is, per method: cells done, running, pending, failed, and worker time.

``progress.md`` in the report (and, for the committed reproduction, the README's status
table, copied by ``scripts/sync_readme_claims.py``): one row per method in the order of
cells.parquet, the cells in progress with their training episodes, and the worker hours
stored (a done cell's wall time, an unfinished cell's time up to its last checkpoint).
"""
from __future__ import annotations

import pandas as pd

STATUSES = ("done", "running", "pending", "failed")


def progress_frame(cells: pd.DataFrame) -> pd.DataFrame:
    """Per method: cells in each status, total, and worker hours stored."""
    rows = []
    for method, g in cells.groupby("method", sort=False):
        counts = g["status"].value_counts()
        rows.append({"method": str(method), **{s: int(counts.get(s, 0)) for s in STATUSES},
                     "cells": len(g), "worker_hours": float(g["wall_s"].fillna(0.0).sum()) / 3600.0})
    return pd.DataFrame(rows, columns=["method", *STATUSES, "cells", "worker_hours"])


def progress_markdown(cells: pd.DataFrame) -> str:
    """The progress table and the cells in progress, as Markdown."""
    frame = progress_frame(cells)
    lines = ["| method | done | running | pending | failed | cells | worker hours |",
             "|---|---|---|---|---|---|---|"]
    lines += [f"| {r.method} | {r.done} | {r.running} | {r.pending} | {r.failed} | {r.cells} | {r.worker_hours:.1f} |"
              for r in frame.itertuples()]
    lines.append(f"| all | {frame['done'].sum()} | {frame['running'].sum()} | {frame['pending'].sum()} | "
                 f"{frame['failed'].sum()} | {frame['cells'].sum()} | {frame['worker_hours'].sum():.1f} |")
    running = cells[cells["status"] == "running"]
    if len(running):
        lines += ["", "In progress: " + "; ".join(
            f"{r.method} N = {r.n_robots}, p = {r.loss_p:g}, seed {r.seed} at {int(r.train_episodes_done):,} "
            f"of {int(r.episodes):,} training episodes" for r in running.itertuples()) + "."]
    return "\n".join(lines) + "\n"
