"""The warehouse: layouts, the batched numpy core, the lossy channel, PettingZoo adapter."""
from __future__ import annotations

from envs.actions import Action
from envs.config import EnvConfig
from envs.core import StepResult, WarehouseCore
from envs.layouts import Layout, load_layout

__all__ = ["Action", "EnvConfig", "Layout", "StepResult", "WarehouseCore", "load_layout"]
