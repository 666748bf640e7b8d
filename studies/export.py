"""A study's trials as Parquet, its parameter importances, and its best configuration.

``results/studies/<study>/trials.parquet`` holds one row per trial (``TRIAL_COLUMNS`` plus
one column per searched parameter), written atomically beside the journal; it reads back
to the same frame. ``importances.json`` holds Optuna's parameter importances (or why there
are none) and ``study.json`` the study's config (settings, space, search plan, pruner), so
the report needs only these files, whatever the storage.
``best_grid_snippet`` renders the best configuration as a grid file (bench/design/grid_files.py)
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

from bench.store.study_files import CONFIG_FILE, IMPORTANCES_FILE, TRIALS_FILE
from envs.atomic import atomic_file
from envs.errors import BenchError
from studies.points import best_point
from studies.space import ordered, plain
from studies.storage import CONFIG_ATTR, REPLICATE, RETRY_OF
from studies.trial_columns import FILTER_RATES, TRIAL_COLUMNS, param_columns

MIN_IMPORTANCE_TRIALS = 10  # complete trials before fANOVA importances are computed
IMPORTANCE_CAVEAT = (
    "fANOVA importances from {n} complete trials of a noisy objective (pruned trials left "
    "out): a rough ranking of which parameter moved the objective in this study, not a "
    "measured effect; compare the per-configuration means and CIs instead.")


def trials_frame(study: optuna.Study) -> pd.DataFrame:
    """One row per trial: state, objective value(s), evaluation means, searched parameters.

    ``value`` is the (first) objective, ``value_return`` the second objective of a
    multi-objective study (NaN otherwise); ``intermediate_json`` maps step -> reported value.
    """
    trials = study.get_trials(deepcopy=False)
    names = ordered({p for t in trials for p in t.params})
    rows = [_row(study.study_name, t, names) for t in trials]
    frame = pd.DataFrame(rows, columns=[*TRIAL_COLUMNS, *names])
    ints = [n for n in names if all(isinstance(t.params.get(n), int) and not isinstance(t.params.get(n), bool)
                                    for t in trials if n in t.params)]
    for col in ("number", "seed", "replicate", "retry_of", "last_step", "pruned_at_step", "prune_n",
                "episodes", *ints):
        frame[col] = frame[col].astype("Int64")
    for col in ("value", "value_return", "success_rate", "team_return", *FILTER_RATES, "prune_rho", "wall_s",
                "duration_s"):
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
        **{key: ua.get(key, math.nan) for key in FILTER_RATES},
        "seed": ua.get("seed"), "replicate": ua.get(REPLICATE), "cell_id": ua.get("cell_id"),
        "retry_of": ua.get(RETRY_OF), "last_step": t.last_step,
        "pruned_at_step": ua.get("pruned_at_step"), "prune_rho": ua.get("prune_rho", math.nan),
        "prune_n": ua.get("prune_n"),
        "episodes": ua.get("episodes"), "wall_s": ua.get("wall_s", math.nan),
        "datetime_start": t.datetime_start, "datetime_complete": t.datetime_complete,
        "duration_s": duration,
        "intermediate_json": json.dumps({str(k): v for k, v in sorted(t.intermediate_values.items())}),
        "error": ua.get("error"),
        **{n: t.params.get(n) for n in names},
    }


def write_trials(study: optuna.Study, directory: Path, extra: dict[str, Any] | None = None) -> Path:
    """``directory/trials.parquet`` (atomic), ``importances.json`` and ``study.json`` (the
    stored config plus ``extra``, e.g. the resolved search plan and warm-up step)."""
    frame = trials_frame(study)
    path = directory / TRIALS_FILE
    with atomic_file(path) as fh:
        frame.to_parquet(fh, index=False)
    with atomic_file(directory / IMPORTANCES_FILE) as fh:
        fh.write(json.dumps(importances(study), indent=1, sort_keys=True).encode())
    config = {"study": study.study_name, **dict(study.user_attrs.get(CONFIG_ATTR) or {}), **(extra or {})}
    with atomic_file(directory / CONFIG_FILE) as fh:
        fh.write(json.dumps(config, indent=1, sort_keys=True, default=str).encode())
    return path


def read_trials(path: Path) -> pd.DataFrame:
    try:
        return pd.read_parquet(path)
    except Exception as exc:
        raise BenchError(f"cannot read study trials {str(path)!r}: {exc}") from None


def importances(study: optuna.Study) -> dict[str, Any]:
    """``{"importances": {param: share}, "reason": str | None, "caveat": str | None}`` for
    the first objective.

    fANOVA on a handful of noisy trials ranks noise (issue #16: 6-7 trials), so importances
    are computed only from ``MIN_IMPORTANCE_TRIALS`` complete trials and a parameter that
    varies; otherwise they are empty and ``reason`` says why. ``caveat`` goes with them.
    """
    complete = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    varying = [p for p in ordered({p for t in complete for p in t.params})
               if len({t.params.get(p) for t in complete}) > 1]
    if len(complete) < MIN_IMPORTANCE_TRIALS or not varying:
        return {"importances": {}, "caveat": None,
                "reason": f"too few trials for importances: {len(complete)} complete, "
                f"{len(varying)} varying parameter(s); need {MIN_IMPORTANCE_TRIALS} and 1"}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            imp = optuna.importance.get_param_importances(
                study, params=varying, target=lambda t: t.values[0])
    except (RuntimeError, ValueError) as exc:
        return {"importances": {}, "reason": f"importances unavailable: {exc}", "caveat": None}
    return {"importances": {k: float(v) for k, v in imp.items()}, "reason": None,
            "caveat": IMPORTANCE_CAVEAT.format(n=len(complete))}


def replicates_of(study: optuna.Study) -> int:
    """Replicates per configuration the study was created with (2 for older studies)."""
    return int((study.user_attrs.get(CONFIG_ATTR) or {}).get("replicates", 2))


def best_configuration(study: optuna.Study) -> pd.Series:
    """The configuration with the highest mean objective over its replicates, with its CI
    (studies/points.py ``best_point``; BenchError while no configuration qualifies)."""
    from studies.schedule import resolve_mode
    from studies.space import space_size

    if not study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)):
        raise BenchError(f"study {study.study_name!r} has no complete trial yet")
    config = study.user_attrs.get(CONFIG_ATTR) or {}
    space = config.get("space") or {}
    exhaustive = bool(space) and resolve_mode(config.get("search", "auto"), space) == "grid"
    return best_point(trials_frame(study), replicates_of(study), space_size(space) if exhaustive else None)


def best_grid_snippet(study: optuna.Study) -> str:
    """The best configuration (highest mean over replicates) as a TOML grid file for
    ``bench run --grid-file``.

    The base cell repeats the study's N, p, layout, Z and budgets with the best
    parameters; raise ``episodes``/``eval_episodes`` for a full-length run.
    """
    best = best_configuration(study)
    names = param_columns(trials_frame(study))
    settings = dict(study.user_attrs.get(CONFIG_ATTR) or {})
    base: dict[str, Any] = {k: settings[k] for k in (
        "method", "n_robots", "loss_p", "groups", "layout", "episodes", "horizon",
        "eval_episodes") if k in settings}
    from bench.design.cells import Cell

    base.update({k: plain(best[k]) for k in names if k in Cell.model_fields})
    params = dict(settings.get("params", {}))
    params.update({k: plain(best[k]) for k in names if k not in Cell.model_fields})
    for key in ("batch_episodes", "eval_chunk"):
        if key in settings:
            params[key] = settings[key]
    label = ", ".join(f"{k}={plain(best[k])}" for k in names)
    lines = [
        f"# best configuration of study {study.study_name!r}: {label}",
        f"# mean objective {best['value']:.4f} over {int(best['complete'])} replicates "
        f"(95% CI {best['ci_low']:.4f} .. {best['ci_high']:.4f}; trials {best['trials']})",
        f"# mean success rate {best['success_rate']:.3f}, mean team return {best['team_return']:.2f}; "
        "budgets are the study's (raise episodes/eval_episodes for a full run)",
        f"name = {_toml(f'tuned-{study.study_name}')}",
        f"description = {_toml(f'best of Optuna study {study.study_name} ({label})')}",
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
