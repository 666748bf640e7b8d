"""The warehouse: layouts, the batched numpy core, the lossy channel, PettingZoo adapter.

The names below load their module on first use (PEP 562), so importing a light module such
as ``envs.errors`` does not pay for the core and SciPy (commands that do not simulate stay
fast).
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from envs.actions import Action
    from envs.config import EnvConfig
    from envs.core import StepResult, WarehouseCore
    from envs.layouts import Layout, load_layout

__all__ = ["Action", "EnvConfig", "Layout", "StepResult", "WarehouseCore", "load_layout"]

# Each public name -> the module that defines it.
_HOMES = {"Action": "envs.actions", "EnvConfig": "envs.config", "Layout": "envs.layouts",
          "StepResult": "envs.core", "WarehouseCore": "envs.core", "load_layout": "envs.layouts"}


def __getattr__(name: str) -> Any:
    """The public name ``name``, imported from its module on first use."""
    if name not in _HOMES:
        raise AttributeError(f"module 'envs' has no attribute {name!r}")
    value = getattr(importlib.import_module(_HOMES[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
