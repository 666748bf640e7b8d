"""Method names -> classes, imported lazily so the CLI starts fast."""
from __future__ import annotations

import importlib

from algorithms.base import Method
from envs.errors import BenchError

METHODS: dict[str, str] = {
    "hierarchical": "algorithms.hierarchical.method:HierarchicalMethod",
    "decentralized": "algorithms.decentralized:DecentralizedMethod",
    "ic3net": "algorithms.ic3net:IC3NetMethod",
    "pibt": "algorithms.pibt:PIBTMethod",
}


def method_class(name: str) -> type[Method]:
    if name not in METHODS:
        raise BenchError(f"unknown method {name!r}; choose one of {', '.join(METHODS)}")
    module, cls = METHODS[name].split(":")
    return getattr(importlib.import_module(module), cls)
