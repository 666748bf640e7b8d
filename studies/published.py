"""The values a committed study gives its method's ``preset = "tuned"`` (issue 47, decision 0215).

A learned method's tuned preset (algorithms/presets.py) holds its values as literals beside
the method, so that a grid file resolves without reading any study. This module computes
what those literals must be from the study's committed files alone (``trials.parquet`` and
``study.json`` under ``reproduction/studies/<study>/``, as ``bench tune`` writes them): the
definition's fixed ``[params]`` (the training protocol it tuned under) plus the searched
values of the best configuration (studies/points.py ``best_point``: the highest mean over
complete, unpruned replicates). tests/studies/test_published_presets.py checks every
published preset against it, so a re-run study that changes its winner fails the suite
until the preset follows, and a preset cannot name a study that has not finished.

May import: bench.store.study_files, envs.errors, studies.*.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from bench.store.study_files import CONFIG_FILE, TRIALS_FILE
from envs.errors import BenchError
from studies.definitions import load_definition
from studies.seeds import PUBLISHED_ROOT

__all__ = ["STUDIES_ROOT", "published_values"]

STUDIES_ROOT = PUBLISHED_ROOT / "studies"  # the committed studies: bench tune --out reproduction/studies


def published_values(definition: str | Path, root: Path = STUDIES_ROOT) -> dict[str, Any]:
    """The tuned preset's values from the committed study of ``definition`` under ``root``:
    the definition's ``[params]`` updated with the best configuration's searched values.
    BenchError (naming the folder) when the study's files are missing or it has not
    finished all of its trials."""
    from studies.export import read_trials
    from studies.points import best_point
    from studies.space import plain

    spec = load_definition(definition)
    folder = root / spec.name
    where = f"study {spec.name!r} ({str(folder)!r})"
    if not (folder / TRIALS_FILE).exists() or not (folder / CONFIG_FILE).exists():
        raise BenchError(f"{where}: no {TRIALS_FILE} and {CONFIG_FILE}; run bench tune --definition "
                         f"{spec.path.name} --out {root} to the end first")
    trials = read_trials(folder / TRIALS_FILE)
    finished = int(trials["state"].isin(["COMPLETE", "PRUNED"]).sum())
    if finished < spec.trials:
        raise BenchError(f"{where}: {finished} of {spec.trials} trials finished; a preset takes the "
                         "winner of a finished study only")
    config = json.loads((folder / CONFIG_FILE).read_text())
    best = best_point(trials, int(config.get("replicates", 2)))
    values: dict[str, Any] = dict(spec.options.get("params", {}))
    values.update({name: plain(best[name]) for name in spec.space()})
    return values
