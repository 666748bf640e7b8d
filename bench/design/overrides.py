"""Command-line overrides of a grid: ``bench run --set key=value`` and ``--axis key=v1,v2``.

``--set horizon=32`` replaces a cell field in every cell of the grid (as if the grid's
base had it; a key the grid crosses as an axis then takes this one value); ``--axis
loss_p=0.1,0.3`` crosses every cell with each value (several ``--axis`` cross each other).
Keys are cell fields (bench/design/cells.py) or ``params.NAME`` for a method
hyperparameter. Values are read as JSON (``32``, ``0.1``, ``true``, ``[0.5, 0.25]``), else
taken as text (``tiny``). Fields the grid resolved from others (``layout = "auto"`` sized
for N, a method's default ``safety_filter``) keep the grid's value: set them too when an
override changes N or the method.

A run directory records its overrides in manifest.json (``overrides``), and a resumed run
must give the same ones (docs/decisions/0203): cells of two override sets never mix in one
run directory unnoticed.
"""
from __future__ import annotations

import itertools
import json
from collections.abc import Iterable, Mapping
from typing import Any

from bench.design.cells import Cell
from bench.design.grids import Grid, dedup
from envs.errors import BenchError

__all__ = ["apply_overrides", "check_resume_overrides", "describe_overrides", "override_cell", "parse_overrides"]

# What a run without overrides records (and what a manifest without the key means).
NO_OVERRIDES: dict[str, dict[str, Any]] = {"set": {}, "axis": {}}


def _value(text: str) -> Any:
    """JSON if it parses (numbers, booleans, lists), else the text itself."""
    try:
        return json.loads(text)
    except ValueError:
        return text


def _split(option: str, item: str) -> tuple[str, str]:
    key, sep, value = item.partition("=")
    key = key.strip()
    if not sep or not key or not value.strip():
        raise BenchError(f"{option} {item!r}: expected KEY=VALUE (e.g. {option} horizon=32)")
    fields = set(Cell.model_fields) - {"params"}  # hyperparameters one by one: params.NAME
    if key not in fields and not (key.startswith("params.") and len(key) > len("params.")):
        raise BenchError(f"{option} {item}: unknown cell field {key!r}; choose from {', '.join(sorted(fields))} "
                         "or params.NAME (a method hyperparameter)")
    return key, value.strip()


def parse_overrides(sets: Iterable[str] = (), axes: Iterable[str] = ()) -> dict[str, dict[str, Any]]:
    """``{"set": {key: value}, "axis": {key: [values]}}`` from the option texts; BenchError
    (one line naming the option) for a malformed item, an unknown key or a key given twice."""
    out: dict[str, dict[str, Any]] = {"set": {}, "axis": {}}
    for option, kind, items in (("--set", "set", sets), ("--axis", "axis", axes)):
        for item in items:
            key, text = _split(option, item)
            if key in out["set"] or key in out["axis"]:
                raise BenchError(f"{option} {item}: {key!r} is given twice (--set and --axis together)")
            if kind == "set":
                out["set"][key] = _value(text)
            else:
                values = [_value(v.strip()) for v in text.split(",")]
                if any(v == "" for v in values):
                    raise BenchError(f"--axis {item}: an empty value; list them as KEY=V1,V2")
                out["axis"][key] = values
    return out


def override_cell(cell: Cell, values: Mapping[str, Any]) -> Cell:
    """``cell`` with ``values`` (cell fields, or ``params.NAME`` for a hyperparameter) set."""
    spec = cell.model_dump()
    params = dict(spec.pop("params"))
    for key, value in values.items():
        if key.startswith("params."):
            params[key.removeprefix("params.")] = value
        else:
            spec[key] = value
    return Cell.make(**spec, params=params)


def _option_text(key: str, value: Any, kind: str) -> str:
    shown = ",".join(json.dumps(v) if not isinstance(v, str) else v for v in value) if kind == "axis" else (
        value if isinstance(value, str) else json.dumps(value))
    return f"--{kind} {key}={shown}"


def apply_overrides(grid: Grid, overrides: Mapping[str, Mapping[str, Any]]) -> Grid:
    """``grid`` with every cell overridden (deduplicated, first-seen order); BenchError naming
    the option whose value is invalid."""
    sets, axes = dict(overrides.get("set", {})), dict(overrides.get("axis", {}))
    if not sets and not axes or not grid.cells:
        return grid
    first = grid.cells[0]
    for kind, table in (("set", sets), ("axis", axes)):  # each option alone first: the error names it
        for key, value in table.items():
            for v in value if kind == "axis" else [value]:
                try:
                    override_cell(first, {key: v})
                except BenchError as exc:
                    raise BenchError(f"{_option_text(key, value, kind)}: {exc}") from None
    combos = [dict(zip(axes, combo, strict=True)) for combo in itertools.product(*axes.values())]
    try:
        cells = dedup(override_cell(cell, {**sets, **combo}) for cell in grid.cells for combo in combos)
    except BenchError as exc:
        raise BenchError(f"{describe_overrides(overrides)}: {exc}") from None
    return Grid(grid.name, f"{grid.description} ({describe_overrides(overrides)})", cells)


def describe_overrides(overrides: Mapping[str, Mapping[str, Any]]) -> str:
    """The options as a user types them, e.g. '--set horizon=32 --axis loss_p=0.1,0.3'."""
    parts = [_option_text(k, v, kind) for kind in ("set", "axis") for k, v in overrides.get(kind, {}).items()]
    return " ".join(parts) or "no overrides"


def check_resume_overrides(manifest: Mapping[str, Any] | None, overrides: Mapping[str, Any], out: str) -> None:
    """Refuse (BenchError) to continue a run directory made with other overrides: its cells
    and these would mix in one run (docs/decisions/0203). A directory without a manifest
    (new) or made before overrides existed (no key: none) is checked like any other."""
    if manifest is None:
        return
    stored = manifest.get("overrides", NO_OVERRIDES)
    now = {"set": dict(overrides.get("set", {})), "axis": dict(overrides.get("axis", {}))}
    if json.dumps(stored, sort_keys=True) != json.dumps(now, sort_keys=True):
        raise BenchError(f"{out!r} was run with {describe_overrides(stored)}, this command gives "
                         f"{describe_overrides(now)}: its cells would mix with these; resume with the same options, "
                         "or use another --out (or --fresh to start this folder over)")
