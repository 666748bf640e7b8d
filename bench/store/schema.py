"""The results store schema, version 2 (documented column by column in docs/results-schema.md).

Every Parquet file the bench writes carries ``schema_version`` in its key-value metadata;
``manifest.json`` carries it too. A reader meeting another version refuses the folder
(BenchError) instead of guessing. Change a schema only together with SCHEMA_VERSION, the
document and the reports.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import pyarrow as pa

from algorithms.common.diagnostic_columns import DIAGNOSTIC_COLUMNS

__all__ = ["CELLS_SCHEMA", "EVAL_SCHEMA", "LOSS_COLUMNS", "METRIC_FIELDS", "SCHEMA_VERSION", "STATUSES", "TRAIN_SCHEMA",
           "VERSION_KEY", "added_columns", "file_version", "rows_to_table", "with_version"]

SCHEMA_VERSION = 2  # 2: eval rows carry execution and scenario; cells carry executions
VERSION_KEY = b"schema_version"  # the Parquet metadata key holding SCHEMA_VERSION

STATUSES = ("pending", "running", "done", "failed")  # a cell's status in cells.parquet

# Columns added to a version-2 table after its first files were written: a file without one
# reads as this value (for superseded_wall_s: no discarded attempt recorded).
ADDED_CELL_COLUMNS = {"superseded_wall_s": 0.0}
# The same for eval tables: the MAPF metrics (algorithms/common/episodes.py MAPF_METRICS) read
# as NaN from a file written before them, so older stores report as they did.
ADDED_EVAL_COLUMNS = {"csr": math.nan, "sum_of_costs": math.nan, "makespan": math.nan, "throughput": math.nan}

# One row per cell: its config, status and progress.
CELLS_SCHEMA = pa.schema([
    pa.field("cell_id", pa.string(), nullable=False),
    pa.field("grid", pa.string()),
    pa.field("method", pa.string()),
    pa.field("n_robots", pa.int64()),
    pa.field("loss_p", pa.float64()),
    pa.field("seed", pa.int64()),
    pa.field("groups", pa.int64()),
    pa.field("ref_size", pa.int64()),
    pa.field("search_radius", pa.int64()),
    pa.field("c_max", pa.int64()),
    pa.field("safety_filter", pa.bool_()),
    pa.field("layout", pa.string()),
    pa.field("episodes", pa.int64()),
    pa.field("horizon", pa.int64()),
    pa.field("eval_episodes", pa.int64()),
    pa.field("on_goal", pa.string()),
    pa.field("loss_model", pa.string()),
    pa.field("executions", pa.string()),  # comma-separated evaluation modes of the cell
    pa.field("params_json", pa.string()),
    pa.field("config_json", pa.string()),
    pa.field("status", pa.string()),
    pa.field("error", pa.string()),
    pa.field("train_episodes_done", pa.int64()),
    pa.field("wall_s", pa.float64()),
    pa.field("superseded_wall_s", pa.float64()),
    pa.field("peak_mem_mb", pa.float64()),
    pa.field("attempts", pa.int64()),
    pa.field("versions_json", pa.string()),
    pa.field("schema_version", pa.int64()),
])

# Per-episode metrics shared by train and eval rows (algorithms/common/episodes.py EVAL_METRICS).
METRIC_FIELDS = [
    pa.field("team_return", pa.float64()),
    pa.field("success_rate", pa.float64()),
    pa.field("collision_rate", pa.float64()),
    pa.field("invalid_rate", pa.float64()),
    pa.field("correction_rate", pa.float64()),
    pa.field("mean_candidates", pa.float64()),
    pa.field("fallback_rate", pa.float64()),
    pa.field("predictor_error", pa.float64()),
    pa.field("payload_scalars_per_step", pa.float64()),
    pa.field("payload_dec_per_step", pa.float64()),
    pa.field("steps", pa.int64()),
]
LOSS_COLUMNS = ("actor_loss", "critic_loss", "predictor_loss")  # the losses of a training row

# One row per cell x training episode; the per-update diagnostics come last:
# a train file written before them reads them as NaN (ADDED_TRAIN_COLUMNS).
TRAIN_SCHEMA = pa.schema(
    [pa.field("cell_id", pa.string(), nullable=False), pa.field("episode", pa.int64(), nullable=False)]
    + METRIC_FIELDS
    + [pa.field(c, pa.float64()) for c in LOSS_COLUMNS]
    + [pa.field("wall_s", pa.float64())]
    + [pa.field(c, pa.float64()) for c in DIAGNOSTIC_COLUMNS]
)
ADDED_TRAIN_COLUMNS = {c: float("nan") for c in DIAGNOSTIC_COLUMNS}


def added_columns(schema: pa.Schema) -> dict[str, float]:
    """The columns of ``schema`` added after its first files were written (name -> the
    value a file without one reads as)."""
    if schema.equals(TRAIN_SCHEMA):
        return ADDED_TRAIN_COLUMNS
    if schema.names == EVAL_SCHEMA.names:  # every reader of eval files: a file older than a column
        return ADDED_EVAL_COLUMNS
    return ADDED_CELL_COLUMNS if schema.equals(CELLS_SCHEMA) else {}


# One row per cell x evaluation episode x execution mode (algorithms/common/execution.py).
EVAL_SCHEMA = pa.schema(
    [pa.field("cell_id", pa.string(), nullable=False), pa.field("episode", pa.int64(), nullable=False),
     pa.field("execution", pa.string(), nullable=False), pa.field("scenario", pa.string())]
    + METRIC_FIELDS
    + [pa.field(name, pa.float64()) for name in ADDED_EVAL_COLUMNS]
)


def with_version(schema: pa.Schema, extra: Mapping[str, str] | None = None) -> pa.Schema:
    """The schema with ``schema_version`` (and optional extra strings) in its metadata."""
    meta = {VERSION_KEY: str(SCHEMA_VERSION).encode()}
    for k, v in (extra or {}).items():
        meta[k.encode()] = str(v).encode()
    return schema.with_metadata(meta)


def _value(field: pa.Field, value: Any) -> Any:
    if value is None:
        return float("nan") if pa.types.is_floating(field.type) else None
    if pa.types.is_integer(field.type):
        if isinstance(value, float) and math.isnan(value):
            return None
        return int(value)
    if pa.types.is_floating(field.type):
        return float(value)
    if pa.types.is_boolean(field.type):
        return bool(value)
    return str(value)


def rows_to_table(
    rows: Sequence[Mapping[str, Any]], schema: pa.Schema, extra_meta: Mapping[str, str] | None = None
) -> pa.Table:
    """Rows (dicts) -> a table with exactly ``schema``'s columns, in order.

    Missing float columns become NaN (a method without that quantity, e.g. no losses for a
    planner); keys not in the schema are dropped; a missing non-float column is an error.
    """
    columns = {}
    for f in schema:
        vals = []
        for r in rows:
            if f.name not in r and not pa.types.is_floating(f.type):
                raise KeyError(f"row has no column {f.name!r}")
            vals.append(_value(f, r.get(f.name)))
        columns[f.name] = pa.array(vals, type=f.type)
    return pa.Table.from_pydict(columns, schema=with_version(schema, extra_meta))


def file_version(metadata: Mapping[bytes, bytes] | None) -> int | None:
    """``schema_version`` of a file's key-value metadata, None when absent or unreadable."""
    if not metadata or VERSION_KEY not in metadata:
        return None
    try:
        return int(metadata[VERSION_KEY])
    except ValueError:
        return None
