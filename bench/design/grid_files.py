"""User grid files (TOML or YAML): a base cell plus list-valued axes to cross.

Example (``my_grid.toml``)::

    name = "radius-sweep"        # optional; default: the file name without extension; a plain
                                 # name (letters, digits, . _ -): the run folder results/<name>
    description = "L x p at N=40"
    seeds = 2                    # optional; replicate over seeds 0..seeds-1 (--seeds wins)

    [base]                       # any Cell field (bench/design/cells.py); defaults fill the rest
    method = "hierarchical"
    n_robots = 40
    episodes = 500
    [base.params]                # method hyperparameters (validated by the method's Params)
    batch_episodes = 8

    [axes]                       # every combination is a cell (cartesian product)
    loss_p = [0.2, 0.4, 0.6]
    search_radius = [1, 2, 3]
    "params.batch_episodes" = [4, 8]   # dotted keys cross method hyperparameters

The same structure in YAML (``.yaml``/``.yml``) works identically.
"""
from __future__ import annotations

import itertools
import json
import re
from pathlib import Path
from typing import Any

from bench.design.cells import Cell
from bench.design.grids import Grid, dedup
from bench.design.limits import limit, reason
from envs.errors import BenchError

try:
    import tomllib
except ImportError:  # pragma: no cover - Python 3.10
    try:
        import tomli as tomllib  # type: ignore[no-redef]  # the same API under its 3.10 name
    except ImportError:
        tomllib = None  # type: ignore[assignment]  # no TOML reader: grid files say so when read

TOP_KEYS = {"name", "description", "seeds", "base", "axes"}


def _parse(path: Path) -> dict[str, Any]:
    try:
        text = path.read_text()
    except OSError as exc:
        raise BenchError(f"grid file {str(path)!r}: cannot read ({exc.strerror})") from None
    suffix = path.suffix.lower()
    try:
        if suffix == ".toml":
            if tomllib is None:  # pragma: no cover - Python 3.10 without tomli
                raise BenchError(f"grid file {str(path)!r}: TOML needs Python 3.11+ or tomli; use YAML")
            data = tomllib.loads(text)
        elif suffix in (".yaml", ".yml"):
            import yaml

            data = yaml.safe_load(text)
        else:
            raise BenchError(f"grid file {str(path)!r}: use a .toml, .yaml or .yml file")
    except BenchError:
        raise
    except Exception as exc:  # tomllib.TOMLDecodeError, yaml.YAMLError
        msg = " ".join(str(exc).split())
        raise BenchError(f"grid file {str(path)!r}: not valid {suffix[1:].upper()}: {msg}") from None
    if not isinstance(data, dict):
        raise BenchError(f"grid file {str(path)!r}: expected a table/mapping at the top level")
    return data


RUN_NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")


def check_run_name(name: object, where: str) -> str:
    """``name`` if it is a plain run name (it becomes the folder results/<name>): letters,
    digits, '.', '_', '-', starting with a letter or digit, at most 100 characters; so no
    path separator, no '..', never absolute. Else BenchError naming ``where``."""
    if not isinstance(name, str) or not RUN_NAME_RE.fullmatch(name) or ".." in name:
        raise BenchError(
            f"{where}: {name!r} is not a plain run name (letters, digits, '.', '_', '-'; no path "
            "separators or '..'); it names the run folder results/<name>"
        )
    return name


def load_grid_file(path: str | Path, seeds: int | None = None) -> Grid:
    """Cells of a user grid file (see the module docstring); errors name file and key."""
    path = Path(path)
    data = _parse(path)
    where = f"grid file {str(path)!r}"
    unknown = sorted(set(data) - TOP_KEYS)
    if unknown:
        raise BenchError(f"{where}: unknown key {unknown[0]!r}; allowed: {', '.join(sorted(TOP_KEYS))}")
    base = data.get("base", {})
    axes = data.get("axes", {})
    if not isinstance(base, dict) or not isinstance(axes, dict):
        raise BenchError(f"{where}: 'base' and 'axes' must be tables")
    for key, values in axes.items():
        if not isinstance(values, list) or not values:
            raise BenchError(f"{where}: axes.{key} must be a non-empty list")
    n_seeds = seeds if seeds is not None else data.get("seeds")
    if n_seeds is not None:
        if not isinstance(n_seeds, int) or isinstance(n_seeds, bool) or n_seeds < 1:
            raise BenchError(f"{where}: seeds must be an integer >= 1, got {n_seeds!r}")
        if n_seeds > limit("seeds"):
            raise BenchError(f"{where}: seeds {n_seeds} is too large{reason('seeds')}")
        axes = {k: v for k, v in axes.items() if k != "seed"}
        axes["seed"] = list(range(n_seeds))
    keys = list(axes)
    cells = []
    for combo in itertools.product(*(axes[k] for k in keys)):
        spec = json.loads(json.dumps(base))  # deep copy of plain data
        for key, value in zip(keys, combo, strict=True):
            if key.startswith("params."):
                spec.setdefault("params", {})[key.removeprefix("params.")] = value
            else:
                spec[key] = value
        if "method" not in spec or "n_robots" not in spec or "loss_p" not in spec:
            missing = [k for k in ("method", "n_robots", "loss_p") if k not in spec][0]
            raise BenchError(f"{where}: every cell needs {missing!r} (in base or axes)")
        try:
            cells.append(Cell.make(**spec))
        except BenchError as exc:
            raise BenchError(f"{where}: {exc}") from None
    name = check_run_name(data["name"], f"{where}: name") if "name" in data else check_run_name(
        path.stem, f"{where}: name (the file name, no 'name' key)")
    return Grid(name, str(data.get("description", f"user grid from {path.name}")), dedup(cells))
