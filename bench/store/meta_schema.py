"""Schemas (pydantic) of the JSON metadata the bench reads back: manifest.json, the key-value
metadata of an eval file, and a study's study.json (docs/results-schema.md).

Each is validated on read; a mismatch is ONE BenchError line naming the file and the field
(``runs: Input should be a valid list``) instead of a TypeError deep in the code, or a
string silently iterated letter by letter. Unknown keys are allowed (a newer bench may
add some), the types of the known ones are not negotiable.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    StrictFloat,
    StrictInt,
    StrictStr,
    ValidationError,
)

from envs.errors import BenchError

Number = StrictInt | StrictFloat


class RunRecord(BaseModel):
    """One invocation of ``bench run`` in the manifest's ``runs``."""

    model_config = ConfigDict(extra="allow")
    grid: StrictStr | None = None
    started: StrictStr | None = None
    ended: StrictStr | None = None
    command: list[StrictStr] | StrictStr | None = None  # sys.argv (older tools: one string)
    git: StrictStr | None = None
    workers: StrictInt | None = None
    wall_s: Number | None = None
    cells_done_before: StrictInt | None = None
    cells_done_in_run: StrictInt | None = None
    cells_done_after: StrictInt | None = None
    machine: dict[str, Any] | None = None
    # Parts filled in after the run (part -> where its value comes from), and parts that have
    # no value (part -> why): a record written by an older bench, or one whose run was killed.
    reconstructed: dict[StrictStr, StrictStr] | None = None
    unrecorded: dict[StrictStr, StrictStr] | None = None


# What a finished invocation's record holds (docs/results-schema.md, manifest.json).
RECORD_PARTS = ("grid", "started", "ended", "command", "git", "machine", "workers", "wall_s",
                "cells_done_before", "cells_done_in_run", "cells_done_after")


def unexplained_parts(record: dict[str, Any]) -> list[str]:
    """Parts of RECORD_PARTS that a run record neither holds nor names in ``unrecorded``."""
    why = record.get("unrecorded") or {}
    return [p for p in RECORD_PARTS if record.get(p) is None and not why.get(p)]


class Manifest(BaseModel):
    """manifest.json of a run directory."""

    model_config = ConfigDict(extra="allow")
    schema_version: StrictInt
    created: StrictStr | None = None
    updated: StrictStr | None = None
    grid: StrictStr | None = None
    command: list[StrictStr] | StrictStr | None = None  # sys.argv (older tools: one string)
    git_sha: StrictStr | None = None
    package_version: StrictStr | None = None
    versions: dict[str, StrictStr] | None = None
    runs: list[RunRecord] = Field(default_factory=list)
    ray: StrictStr | None = None
    workers: StrictInt | None = None


class EvalMeta(BaseModel):
    """Key-value metadata of eval/<cell_id>.parquet (JSON values)."""

    model_config = ConfigDict(extra="allow")
    wall_s: Number | None = None
    peak_mem_mb: Number | None = None
    attempts: StrictInt | None = None
    train_episodes_done: StrictInt | None = None


class StudyConfig(BaseModel):
    """studies/<name>/study.json (studies/export.py): only what readers outside the study use."""

    model_config = ConfigDict(extra="allow")
    run: StrictStr | None = None


def validated(model: type[BaseModel], data: Any, path: Path | str) -> dict[str, Any]:
    """``data`` checked against ``model`` (returned unchanged: the file's own values), else
    BenchError 'invalid <path>: <field>: <message>'."""
    if not isinstance(data, dict):
        raise BenchError(f"invalid {str(path)!r}: expected a JSON object, found {type(data).__name__}")
    try:
        model.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = ".".join(str(p) for p in err["loc"]) or "(top level)"
        more = f" (and {exc.error_count() - 1} more)" if exc.error_count() > 1 else ""
        raise BenchError(f"invalid {str(path)!r}: {loc}: {err['msg']}{more}") from None
    return data
