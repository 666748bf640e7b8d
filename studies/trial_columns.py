"""The columns of a study's trials frame (``trials.parquet``, studies/export.py) and which
of them are the searched parameters: the frame holds ``TRIAL_COLUMNS`` plus one column per
parameter of the study's space."""
from __future__ import annotations

import pandas as pd

from studies.space import ordered

__all__ = ["TRIAL_COLUMNS", "param_columns"]

TRIAL_COLUMNS = (
    "study", "number", "state", "value", "value_return", "success_rate", "team_return",
    "seed", "replicate", "cell_id", "retry_of", "last_step", "pruned_at_step", "prune_rho",
    "prune_n", "episodes", "wall_s",
    "datetime_start", "datetime_complete", "duration_s", "intermediate_json", "error",
)


def param_columns(trials: pd.DataFrame) -> list[str]:
    """The searched parameters present in the frame (``ref_size``, ``search_radius``, ``lr``,
    ...): every column that is not one of ``TRIAL_COLUMNS``."""
    return ordered(c for c in trials.columns if c not in TRIAL_COLUMNS and trials[c].notna().any())
