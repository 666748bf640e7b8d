"""A study's trials as Parquet, its parameter importances, and its best configuration.

``results/studies/<study>/trials.parquet`` holds one row per trial (``TRIAL_COLUMNS`` plus
one column per searched parameter), written atomically beside the journal; it reads back
to the same frame. ``importances.json`` holds Optuna's parameter importances (or why there
are none), so the report needs only these two files, whatever the storage.
``best_grid_snippet`` renders the best configuration as a grid file (bench/grid_files.py)
that ``bench run --grid-file`` accepts.
"""
from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import Any

import optuna
import pandas as pd
from optuna.trial import FrozenTrial, TrialState

from bench.store import atomic_file
from envs.errors import BenchError
from studies.space import PARAMETERS
from studies.storage import CONFIG_ATTR, RETRY_OF

TRIALS_FILE = "trials.parquet"
IMPORTANCES_FILE = "importances.json"
TRIAL_COLUMNS = (
    "study", "number", "state", "value", "value_return", "success_rate", "team_return",
    "seed", "cell_id", "retry_of", "last_step", "pruned_at_step", "episodes", "wall_s",
    "datetime_start", "datetime_complete", "duration_s", "intermediate_json", "error",
)


def trials_frame(study: optuna.Study) -> pd.DataFrame:
    """One row per trial: state, objective value(s), evaluation means, searched parameters.

    ``value`` is the (first) objective, ``value_return`` the second objective of a
    multi-objective study (NaN otherwise); ``intermediate_json`` maps step -> reported value.
    """
    trials = study.get_trials(deepcopy=False)
    names = [p for p in PARAMETERS if any(p in t.params for t in trials)]
    rows = [_row(study.study_name, t, names) for t in trials]
    frame = pd.DataFrame(rows, columns=[*TRIAL_COLUMNS, *names])
    for col in ("number", "seed", "retry_of", "last_step", "pruned_at_step", "episodes", *names):
        frame[col] = frame[col].astype("Int64")
    for col in ("value", "value_return", "success_rate", "team_return", "wall_s", "duration_s"):
        frame[col] = frame[col].astype("float64")
    for col in ("datetime_start", "datetime_complete"):
        frame[col] = pd.to_datetime(frame[col]).astype("datetime64[us]")
    for col in ("study", "state", "cell_id", "intermediate_json", "error"):
        frame[col] = frame[col].astype("string")
    return frame


def _row(study: str, t: FrozenTrial, names: list[str]) -> dict[str, Any]:
    ua = t.user_attrs
    values = list(t.values) if t.values is not None else []
    duration = t.duration.total_seconds() if t.duration is not None else math.nan
    return {
        "study": study, "number": t.number, "state": t.state.name,
        "value": values[0] if values else math.nan,
        "value_return": values[1] if len(values) > 1 else math.nan,
        "success_rate": ua.get("success_rate", math.nan), "team_return": ua.get("team_return", math.nan),
        "seed": ua.get("seed"), "cell_id": ua.get("cell_id"), "retry_of": ua.get(RETRY_OF),
        "last_step": t.last_step, "pruned_at_step": ua.get("pruned_at_step"),
        "episodes": ua.get("episodes"), "wall_s": ua.get("wall_s", math.nan),
        "datetime_start": t.datetime_start, "datetime_complete": t.datetime_complete,
        "duration_s": duration,
        "intermediate_json": json.dumps({str(k): v for k, v in sorted(t.intermediate_values.items())}),
        "error": ua.get("error"),
        **{n: t.params.get(n) for n in names},
    }


def write_trials(study: optuna.Study, directory: Path) -> Path:
    """``directory/trials.parquet`` (atomic) and ``directory/importances.json``."""
    frame = trials_frame(study)
    path = directory / TRIALS_FILE
    with atomic_file(path) as fh:
        frame.to_parquet(fh, index=False)
    with atomic_file(directory / IMPORTANCES_FILE) as fh:
        fh.write(json.dumps(importances(study), indent=1, sort_keys=True).encode())
    return path


def read_trials(path: Path) -> pd.DataFrame:
    try:
        return pd.read_parquet(path)
    except Exception as exc:
        raise BenchError(f"cannot read study trials {str(path)!r}: {exc}") from None


def importances(study: optuna.Study) -> dict[str, Any]:
    """``{"importances": {param: share}, "reason": str | None}`` for the first objective.

    Optuna's default evaluator (fANOVA) needs at least two complete trials and a parameter
    that varies; otherwise the importances are empty and ``reason`` says why.
    """
    complete = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    varying = [p for p in PARAMETERS if len({t.params.get(p) for t in complete}) > 1]
    if len(complete) < 2 or not varying:
        return {"importances": {}, "reason": f"too few trials: {len(complete)} complete, "
                f"{len(varying)} varying parameter(s); need 2 and 1"}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            imp = optuna.importance.get_param_importances(
                study, params=varying, target=lambda t: t.values[0])
    except (RuntimeError, ValueError) as exc:
        return {"importances": {}, "reason": f"importances unavailable: {exc}"}
    return {"importances": {k: float(v) for k, v in imp.items()}, "reason": None}


def best_trial(study: optuna.Study) -> FrozenTrial:
    """The best complete trial; multi-objective: the Pareto trial with the highest success
    rate, team return breaking ties."""
    if not study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)):
        raise BenchError(f"study {study.study_name!r} has no complete trial yet")
    if len(study.directions) == 1:
        return study.best_trial
    return max(study.best_trials, key=lambda t: (t.values[0], t.values[1]))


def best_grid_snippet(study: optuna.Study) -> str:
    """The best configuration as a TOML grid file for ``bench run --grid-file``.

    The base cell repeats the study's N, p, layout, Z and budgets with the best
    parameters; raise ``episodes``/``eval_episodes`` for a full-length run.
    """
    trial = best_trial(study)
    settings = dict(study.user_attrs.get(CONFIG_ATTR) or {})
    base: dict[str, Any] = {k: settings[k] for k in (
        "method", "n_robots", "loss_p", "groups", "layout", "episodes", "horizon",
        "eval_episodes") if k in settings}
    base.update({k: int(v) for k, v in trial.params.items()})
    params = dict(settings.get("params", {}))
    for key in ("batch_episodes", "eval_chunk"):
        if key in settings:
            params[key] = settings[key]
    values = ", ".join(f"{v:.4g}" for v in trial.values)
    lines = [
        f"# best trial {trial.number} of study {study.study_name!r}: objective {values}",
        f"# success rate {trial.user_attrs.get('success_rate', float('nan')):.3f}, "
        f"team return {trial.user_attrs.get('team_return', float('nan')):.2f}; "
        "budgets are the study's (raise episodes/eval_episodes for a full run)",
        f"name = {_toml(f'tuned-{study.study_name}')}",
        f"description = {_toml(f'best of Optuna study {study.study_name} (trial {trial.number})')}",
        "", "[base]",
        *(f"{k} = {_toml(v)}" for k, v in base.items()),
    ]
    if params:
        lines += ["", "[base.params]", *(f"{k} = {_toml(v)}" for k, v in sorted(params.items()))]
    return "\n".join(lines) + "\n"


def _toml(value: Any) -> str:
    """A TOML scalar (strings as JSON basic strings, which TOML reads the same)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value) if isinstance(value, int) or math.isfinite(value) else "nan"
    if isinstance(value, str):
        return json.dumps(value)
    raise BenchError(f"cannot write {value!r} into a grid file")
