"""``bench export --format csv``: a run's tables as tidy CSV (one row per observation, one
column per variable), for spreadsheets, R or any evaluator that reads CSV.

``cells.csv`` is cells.parquet; ``train.csv`` one row per cell and training episode and
``eval.csv`` one row per cell, evaluation episode and execution mode, each with the cell's
identifying config columns (method, n_robots, loss_p, seed, layout, loss_model, grid)
joined in front, so a row stands on its own. Floats in full precision (shortest round-trip text), NaN as an
empty field.
"""
from __future__ import annotations

import pandas as pd

KEYS = ["cell_id", "grid", "method", "n_robots", "loss_p", "seed", "layout", "loss_model"]


def tidy_tables(cells: pd.DataFrame, train: pd.DataFrame, evals: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """``{"cells": ..., "train": ..., "eval": ...}`` ready to write (rows sorted)."""
    keys = cells[[k for k in KEYS if k in cells]]
    out = {"cells": cells.sort_values("cell_id").reset_index(drop=True)}
    for name, frame, order in (("train", train, ["cell_id", "episode"]),
                               ("eval", evals, ["cell_id", "execution", "episode"])):
        joined = keys.merge(frame, on="cell_id", how="inner")
        out[name] = joined.sort_values(order, kind="stable").reset_index(drop=True)
    return out


def to_csv_bytes(frame: pd.DataFrame) -> bytes:
    return frame.to_csv(index=False).encode()
