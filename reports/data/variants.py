"""Which variant of its method each cell is, so that no table or test pools variants.

A store can hold cells of one (method, N, p) that differ in more than their seed: the
ablation grid's eight hierarchical variants (``messages="oracle"``, ``share_params``, ...),
or a user's grid file beside the paper grid. Their rows are not seeds of one
configuration, and the seed is the statistical unit of every interval and test. So:

* ``cell_variants`` labels each cell by the settings in which it differs from the other
  cells of its (method, N, p, task) group (a lifelong cell is not a variant of a one-shot
  one: each is its task's default and is reported in its task's section): the keys whose
  values vary within the group (the resolved hyperparameters of ``params_json`` and the cell's configuration, seed
  excluded), written ``key=value`` where the cell's value is not the method's default (a
  key that is not a hyperparameter, such as ``episodes``, is always written). A group
  whose cells agree on everything has one variant, labelled ``""``, whatever its settings.
* The summary and the success table give each variant its own row (``variant_suffix``);
  the figures, Table I and the claims use the default variant only (``default_rows``):
  the paper's method at the method's defaults, the others' own defaults (docs/decisions/0048).
* A report built with ``--against REF`` headlines the run, not the reference: in a group
  that holds cells of the run itself and cells merged from REF (``MERGED`` marks those),
  labels say how a cell departs from the settings the run's own cells share there, so the
  run's cells are the default variant and REF's are labelled (``protocol=paper`` beside a
  run under ``protocol = "mappo"``; docs/decisions/0243).
"""
from __future__ import annotations

import json
from typing import Any

import pandas as pd

from algorithms.registry import find_method
from bench.design.cells import LATER_FIELDS

GROUP = ("method", "n_robots", "loss_p", "task")  # a one-shot and a lifelong cell are never variants of one another
MERGED = "merged_from_against"  # bool column reports.data.against adds: True for REF's cells
NOT_A_VARIANT = frozenset({"seed", "method", "n_robots", "loss_p", "params"})  # group keys, the seed, raw overrides


def _settings(row: Any) -> dict[str, str]:
    """Every setting of a cell but its group and seed, values as canonical JSON."""
    config_json, params_json = getattr(row, "config_json", None), getattr(row, "params_json", None)
    config = json.loads(config_json) if isinstance(config_json, str) and config_json else {}
    params = json.loads(params_json) if isinstance(params_json, str) and params_json else {}
    merged = {k: v for k, v in config.items() if k not in NOT_A_VARIANT}
    merged.update(params)
    return {k: json.dumps(v, sort_keys=True) for k, v in merged.items()}


def _defaults(method: str) -> dict[str, str]:
    cls = find_method(method)
    if cls is None:
        return {}
    fields = cls.Params.model_fields
    return {k: json.dumps(f.default, sort_keys=True) for k, f in fields.items() if not f.is_required()}


def _unset(key: str, settings: dict[str, str]) -> bool:
    """A cell field added later (``LATER_FIELDS``: e.g. ``delay``), which a cell stores only
    when it departs from the default (docs/decisions/0209), is at its default where absent:
    the cell is the group's default variant in that key (a lifelong run's delay-0 cells
    beside its delay-2 cells; docs/decisions/0218). Any other absent setting is named."""
    return key in LATER_FIELDS and key not in settings


def _reference(defaults: dict[str, str], group: pd.DataFrame,
               settings: dict[str, dict[str, str]]) -> dict[str, str]:
    """What a group's labels are relative to: the method's defaults, overridden, in a group
    mixing the run's own cells with cells merged from ``--against``, by every setting the
    run's own cells there share (see the module doc)."""
    if MERGED not in group or not group[MERGED].any() or group[MERGED].all():
        return defaults
    own = [settings[cid] for cid in group.loc[~group[MERGED].astype(bool), "cell_id"]]
    shared = {k: own[0][k] for k in own[0] if all(s.get(k) == own[0][k] for s in own)}
    return {**defaults, **shared}


def cell_tasks(cells: pd.DataFrame) -> pd.Series:
    """cell_id -> the cell's task, from its stored configuration (a cell stores ``task`` only
    when it is not the default "one-shot", docs/decisions/0209), so a pending cell has one too."""
    def task(config_json: object) -> str:
        config = json.loads(config_json) if isinstance(config_json, str) and config_json else {}
        return str(config.get("task", "one-shot"))
    if cells.empty or "config_json" not in cells:
        return pd.Series("one-shot", index=cells.get("cell_id", pd.Series(dtype=object)), dtype=object)
    return pd.Series([task(c) for c in cells["config_json"]], index=cells["cell_id"], dtype=object)


def cell_variants(cells: pd.DataFrame) -> pd.Series:
    """cell_id -> variant label ("" for a group's default variant; see the module doc)."""
    labels: dict[str, str] = {}
    if cells.empty:
        return pd.Series(labels, dtype=object)
    cells = cells.assign(task=cells["cell_id"].map(cell_tasks(cells)).to_numpy())
    for (method, _, _, _), group in cells.groupby(list(GROUP), sort=False):
        defaults = _defaults(str(method))  # a hyperparameter a cell does not store is at its default
        settings = {row.cell_id: {**defaults, **_settings(row)} for row in group.itertuples()}
        keys = sorted(set().union(*settings.values()))
        varying = [k for k in keys if len({s.get(k) for s in settings.values()}) > 1]
        reference = _reference(defaults, group, settings)
        for cid, s in settings.items():
            labels[cid] = ", ".join(f"{k}={json.loads(s[k]) if k in s else None}" for k in varying
                                    if (k not in reference or s.get(k) != reference[k]) and not _unset(k, s))
    return pd.Series(labels, dtype=object)


def variant_suffix(label: str) -> str:
    """What a method's display label gets for a variant: "" or " [key=value, ...]"."""
    return f" [{label}]" if label else ""


def default_rows(rows: pd.DataFrame, variants: pd.Series) -> pd.DataFrame:
    """The rows (any table with ``cell_id``) of cells of their group's default variant."""
    if rows.empty or "cell_id" not in rows:
        return rows
    return rows[rows["cell_id"].map(variants).fillna("").eq("")]
