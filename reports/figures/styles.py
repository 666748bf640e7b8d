"""The report's method table: how each method is drawn (colour, line style, legend rank).

Styling is the report's business, not the method's. A package registers the styles of its
methods in the entry-point group ``warehouse_marl_bench.styles`` (``name = "module:TABLE"``,
a mapping of method name to ``Style``); the paper's wing registers the built-ins' colours
there. A method without an entry gets a default: a colour of the colour-blind palette
picked by a stable hash of its name (so two plugins are told apart), a solid line, ranked
after the registered ones. A plugin written against the older contract, which declares
``color``, ``line_style`` or ``legend_rank`` on its ``Method`` class, keeps its look and
gets a ``DeprecationWarning`` naming the entry-point group.
"""
from __future__ import annotations

import warnings
import zlib
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache, lru_cache
from importlib import metadata

from algorithms.base import UNRANKED, Method
from algorithms.registry import find_method
from envs.errors import BenchError

__all__ = ["DEFAULT_PALETTE", "STYLE_ENTRY_POINT_GROUP", "Style", "method_style_of", "registered_styles"]

STYLE_ENTRY_POINT_GROUP = "warehouse_marl_bench.styles"
# seaborn's "colorblind" palette without the four colours the built-ins use
DEFAULT_PALETTE = ("#d55e00", "#cc78bc", "#ca9161", "#fbafe4", "#ece133", "#56b4e9")


@dataclass(frozen=True)
class Style:
    """A method's look in every figure and its position in legends and tables."""

    color: str  # '#rrggbb'
    line_style: str = "-"  # matplotlib line style, so lines stay apart in greyscale
    rank: int = UNRANKED  # lower first


@lru_cache(maxsize=1)
def registered_styles() -> Mapping[str, Style]:
    """Method name -> Style from every table of entry-point group ``warehouse_marl_bench.styles``."""
    out: dict[str, Style] = {}
    for ep in metadata.entry_points(group=STYLE_ENTRY_POINT_GROUP):
        for name, style in dict(ep.load()).items():
            if name in out and out[name] != style:
                raise BenchError(f"method {name!r} has two styles (entry point {ep.value!r})")
            out[name] = style
    return out


def _declared(cls: type[Method]) -> Style | None:
    """The style an older plugin declares on its class, None when it declares none."""
    attrs = {a: getattr(cls, a) for a in ("color", "line_style", "legend_rank")}
    if all(attrs[a] == getattr(Method, a) for a in attrs):
        return None
    warnings.warn(f"method {cls.__name__}: color, line_style and legend_rank on the Method class are deprecated; "
                  f"register a Style in the entry-point group {STYLE_ENTRY_POINT_GROUP!r} "
                  "(docs/decisions/0207)", DeprecationWarning, stacklevel=3)
    return Style(str(attrs["color"]), str(attrs["line_style"]), int(attrs["legend_rank"]))


@cache
def method_style_of(method: str) -> Style:
    """The style of ``method`` (a registered name or a ``module:Class`` path): the report's
    table, else what an older plugin declares (deprecated), else the default."""
    table = registered_styles()
    if method in table:
        return table[method]
    cls = find_method(method)
    declared = _declared(cls) if cls is not None else None
    if declared is not None:
        return declared
    return Style(DEFAULT_PALETTE[zlib.crc32(method.encode()) % len(DEFAULT_PALETTE)])
