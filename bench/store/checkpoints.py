"""Reading a cell's checkpoint safely: tensors and plain data only, never a pickle.

``RunStore.write_checkpoint`` writes ``{"format": CHECKPOINT_FORMAT, "schema_version": ...,
**payload}`` with ``torch.save``; ``load_checkpoint`` reads it back with
``weights_only=True`` and names what is wrong with a foreign, corrupt or too new file
(SPEC 7: no pickle from a results folder is executed). Both the store and the integrity
checks use it.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from bench.store.schema import SCHEMA_VERSION
from envs.errors import BenchError

__all__ = ["CHECKPOINT_FORMAT", "CHECKPOINT_VERSIONS", "checkpoint_cell", "checkpoint_name", "load_checkpoint",
           "short_error"]

CHECKPOINT_FORMAT = "warehouse-marl-bench/checkpoint"
# Results schema versions whose checkpoints this bench loads: version 2 changed the eval
# rows (execution modes) only, not the checkpoint (cell JSON and the method's state_dict).
CHECKPOINT_VERSIONS = (1, SCHEMA_VERSION)


# checkpoints/<method>-<cell_id>.pt, or <cell_id>.pt as written before names carried the method
_NAME = re.compile(r"(?:[a-z0-9_]+(?:-[a-z0-9_]+)*-)?(?P<cell>[0-9a-f]{12})\.pt")


def checkpoint_name(cell_id: str, method: str | None = None) -> str:
    """The file name of a cell's checkpoint: ``<method>-<cell_id>.pt`` (a ``module:Class``
    method by its class name, lowercased), so a listing of checkpoints/ says whose each
    is; ``<cell_id>.pt`` without a method (the name of checkpoints written before)."""
    if not method:
        return f"{cell_id}.pt"
    slug = re.sub(r"[^a-z0-9_]+", "-", method.rsplit(":", 1)[-1].lower()).strip("-")
    return f"{slug}-{cell_id}.pt" if slug else f"{cell_id}.pt"


def checkpoint_cell(name: str) -> str | None:
    """The cell id of a checkpoint file name, either form; None when ``name`` is none."""
    m = _NAME.fullmatch(name)
    return m["cell"] if m else None


def short_error(exc: BaseException) -> str:
    """An exception's text on one line, at most 200 characters."""
    return " ".join(str(exc).split())[:200]


def load_checkpoint(path: str | Path) -> dict[str, Any]:
    """A bench checkpoint, loaded with ``weights_only=True`` (no pickle is executed).

    Keys: format, schema_version, cell (canonical cell JSON), method, episodes_done,
    wall_s, peak_mem_mb, attempts, state (the method's state_dict).
    """
    import pickle

    import torch

    path = Path(path)
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise BenchError(f"checkpoint {str(path)!r} does not exist") from None
    except pickle.UnpicklingError as exc:
        # Never pass on torch's text: it advises weights_only=False, which would execute code
        # from a results folder. A refused global is named; anything else is corruption.
        found = re.search(r"Unsupported global: GLOBAL (\S+)", str(exc))
        if found is None:
            tail = str(exc).partition("WeightsUnpickler error:")[2]
            why = next((ln.strip() for ln in tail.splitlines() if ln.strip()), "not a torch file")
            raise BenchError(f"corrupt checkpoint {str(path)!r}: {why[:200]}") from None
        raise BenchError(
            f"refusing checkpoint {str(path)!r}: it holds a pickled Python object "
            f"({found.group(1)}), and the bench loads only tensors and plain data "
            "(weights_only=True) so that no code from a results folder is executed; it was not "
            "written by this bench"
        ) from None
    except Exception as exc:  # torch raises many types for truncated or foreign files
        raise BenchError(f"corrupt checkpoint {str(path)!r}: {short_error(exc)}") from None
    if not isinstance(data, dict) or data.get("format") != CHECKPOINT_FORMAT:
        raise BenchError(f"{str(path)!r} is not a bench checkpoint")
    if data.get("schema_version") not in CHECKPOINT_VERSIONS:
        raise BenchError(
            f"checkpoint {str(path)!r} has schema version {data.get('schema_version')}, "
            f"this bench reads versions {', '.join(map(str, CHECKPOINT_VERSIONS))}"
        )
    return data
