"""The one place methods are resolved: registered names and ``module:Class`` paths.

A method is named either

* by a **registered name**: every installed distribution registers its methods in the
  entry-point group ``warehouse_marl_bench.methods`` (``name = "module:Class"``); the four
  built-ins register exactly this way in this package's ``pyproject.toml``; or
* by a **module path** ``"package.module:Class"``, importable from ``sys.path`` (e.g. a
  package on ``PYTHONPATH`` that is not installed).

``method_class(spec)`` returns the class for either form, ``available()`` lists the
registered ones with where they come from, ``describe(spec)`` what ``bench methods`` prints.
Classes are imported lazily (the CLI starts fast); workers resolve the same spec the
driver stored, so a cell of a ``module:Class`` method runs wherever that module imports.
"""
from __future__ import annotations

import contextlib
import importlib
import re
import sys
from dataclasses import dataclass
from functools import cache, lru_cache
from importlib import metadata
from typing import Any

from algorithms.base import Method
from envs.errors import BenchError

__all__ = ["ENTRY_POINT_GROUP", "MethodInfo", "available", "describe", "find_method", "is_builtin", "is_path",
           "method_class", "method_target", "register", "unregister"]

ENTRY_POINT_GROUP = "warehouse_marl_bench.methods"  # where an installed package registers a method
_PATH_RE = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_]\w*$")
_NAME_RE = re.compile(r"^[a-z][a-z0-9_\-]*$")
_OWN_PACKAGE = "algorithms."  # the built-ins' modules: they may hold their own names


@dataclass(frozen=True)
class MethodInfo:
    """A registered method: its name, ``module:Class`` target and the distribution that
    registered it (``source``: ``built-in`` for this package, else ``entry point (dist)``)."""

    name: str
    target: str
    source: str


def is_path(spec: str) -> bool:
    """Whether ``spec`` is a ``module:Class`` path rather than a registered name."""
    return bool(_PATH_RE.match(spec))


_IN_PROCESS: dict[str, MethodInfo] = {}


def register(name: str, target: str) -> None:
    """Register ``name`` -> ``module:Class`` in this process only (tests, notebooks). A run
    stores the name, so ``bench report`` in another process needs the entry point (or the
    cells named as ``module:Class``), see docs/extending.md."""
    if not _NAME_RE.match(name) or not is_path(target):
        raise BenchError(f"register({name!r}, {target!r}): a lowercase name and a module:Class target")
    _IN_PROCESS[name] = MethodInfo(name, target, "registered in this process")
    method_class.cache_clear()


def unregister(name: str) -> None:
    """Undo ``register(name, ...)``."""
    _IN_PROCESS.pop(name, None)
    method_class.cache_clear()


def available() -> dict[str, MethodInfo]:
    """Registered methods by name: the entry points and this process's ``register`` calls."""
    return dict(sorted({**_entry_points(), **_IN_PROCESS}.items()))


@lru_cache(maxsize=1)
def _entry_points() -> dict[str, MethodInfo]:
    """Methods of entry-point group ``warehouse_marl_bench.methods``; BenchError when two
    distributions register one name with different targets."""
    out: dict[str, MethodInfo] = {}
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        dist = ep.dist.name if ep.dist is not None else "unknown"
        source = "built-in" if dist == "warehouse-marl-bench" else f"entry point ({dist})"
        if not _NAME_RE.match(ep.name):
            raise BenchError(f"method entry point {ep.name!r} of {dist}: a method name is lowercase "
                             "letters, digits, '_' or '-'")
        old = out.get(ep.name)
        if old is not None and old.target != ep.value:
            raise BenchError(f"method {ep.name!r} is registered twice: {old.target} ({old.source}) "
                             f"and {ep.value} ({source})")
        out[ep.name] = MethodInfo(ep.name, ep.value, source)
    if not out:
        raise BenchError(f"no method is registered in entry-point group {ENTRY_POINT_GROUP!r}: "
                         "install this package (`pip install -e .`) rather than running it from source")
    return out


def _import(target: str, what: str) -> type[Method]:
    """The class at ``target``; one BenchError naming it whatever its import raises (D13),
    with anything the import prints sent to stderr (D14: stdout stays machine-readable)."""
    module, _, attr = target.partition(":")
    try:
        with contextlib.redirect_stdout(sys.stderr):
            cls = getattr(importlib.import_module(module), attr)
    except Exception as exc:  # an outside module may raise anything at import (SyntaxError too)
        text = " ".join(str(exc).split())[:200]
        raise BenchError(f"method {what}: cannot import {target} ({type(exc).__name__}: {text})") from None
    if not (isinstance(cls, type) and issubclass(cls, Method)):
        raise BenchError(f"method {what}: {target} is not a subclass of algorithms.base.Method")
    _check_names(cls, target, what)
    return cls


def _check_names(cls: type[Method], target: str, what: str) -> None:
    """BenchError when a method outside this package takes a built-in's ``name`` or label
    (``display_name``): two leaderboard rows would read alike (D23)."""
    if target.startswith(_OWN_PACKAGE):
        return
    mine_name = getattr(cls, "name", None)
    mine_label = cls.display_name or mine_name
    for name, info in _entry_points().items():
        if info.source != "built-in":
            continue
        other = _import(info.target, repr(name))
        for field, mine, theirs in (("name", mine_name, other.name), ("display name", mine_label, other.label())):
            if mine is not None and str(mine).casefold() == str(theirs).casefold():
                raise BenchError(f"method {what}: {target} declares the {field} {mine!r} of the built-in method "
                                 f"{name!r}; give it a name and display_name of its own")


@cache
def method_class(spec: str) -> type[Method]:
    """The Method class of a registered name or a ``module:Class`` path; one BenchError
    naming the spec otherwise."""
    if is_path(spec):
        return _import(spec, repr(spec))
    methods = available()
    if spec not in methods:
        raise BenchError(f"unknown method {spec!r}; choose one of {', '.join(methods)} "
                         "or give one as module:Class (`bench methods` lists them)")
    return _import(methods[spec].target, repr(spec))


def is_builtin(spec: str) -> bool:
    """Whether ``spec`` names one of this package's own methods (a failure in it is a bug to
    show in full; an outside method's failure is one line naming it)."""
    info = available().get(spec) if not is_path(spec) else None
    return info is not None and info.source == "built-in"


def find_method(spec: str) -> type[Method] | None:
    """``method_class(spec)``, or None when it cannot be resolved here (a report of a run
    whose plugin is not installed on this machine still builds from the stored rows)."""
    try:
        return method_class(spec)
    except BenchError:
        return None


def method_target(spec: str) -> str:
    """``module:Class`` of a method spec (what a worker imports); BenchError if unknown."""
    if is_path(spec):
        return spec
    method_class(spec)  # the one-line error for an unknown name
    return available()[spec].target


def describe(spec: str) -> dict[str, Any]:
    """What ``bench methods`` shows of one method: its traits, hyperparameters and presets."""
    cls = method_class(spec)
    info = available().get(spec)
    params = {name: (None if f.is_required() else f.default, f.description or "")
              for name, f in cls.Params.model_fields.items()}
    return {
        "name": spec, "display_name": cls.label(), "source": info.source if info else "module path",
        "target": info.target if info else spec, "learned": cls.learned,
        "executions": ", ".join(cls.execution_modes()), "safety_filter": cls.safety_filter_default,
        "payload": cls.payload_model, "color": cls.color, "params": params,
        "presets": {name: {"values": dict(p.values), "source": p.source, "published": not p.pending}
                    for name, p in sorted(cls.presets.items())},  # beside the implicit "paper" (the defaults)
    }
