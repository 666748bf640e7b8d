"""The columns of a study's trials frame (``trials.parquet``, studies/export.py) and which
of them are the searched parameters: the frame holds ``TRIAL_COLUMNS`` plus one column per
parameter of the study's space."""
from __future__ import annotations

import pandas as pd

from studies.space import ordered

__all__ = ["FILTER_RATES", "TRIAL_COLUMNS", "param_columns"]

# The safety filter's rates a trial records from its final evaluation (NaN for a method without a
# filter): the fallback and correction rates that stand beside every hierarchical success number.
FILTER_RATES = ("fallback_rate", "correction_rate")

TRIAL_COLUMNS = (
    "study", "number", "state", "value", "value_return", "success_rate", "team_return",
    "fallback_rate", "correction_rate",
    "seed", "replicate", "cell_id", "retry_of", "last_step", "pruned_at_step", "prune_rho",
    "prune_n", "episodes", "wall_s",
    "datetime_start", "datetime_complete", "duration_s", "intermediate_json", "error",
)


def param_columns(trials: pd.DataFrame) -> list[str]:
    """The searched parameters present in the frame (``ref_size``, ``search_radius``, ``lr``,
    ...): every column that is not one of ``TRIAL_COLUMNS``."""
    return ordered(c for c in trials.columns if c not in TRIAL_COLUMNS and trials[c].notna().any())
