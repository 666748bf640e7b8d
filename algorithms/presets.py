"""Named presets of a method's parameters: ``preset = "tuned"`` in a grid file.

A method declares its presets beside its ``Params`` (``Method.presets``, a name -> ``Preset``
mapping). ``"paper"`` is every method's implicit preset: the ``Params`` defaults and the
cell's own defaults, today's behaviour, which a cell does not record (its id is unchanged).
Any other preset is a set of values -- cell fields the method declares (``ref_size``,
``search_radius``, ``c_max``, ``safety_filter``) or ``Params`` fields -- that a cell takes
where the grid file leaves them unset; the cell then records the preset's name *and* the
values, so its id changes whenever the values do.

A preset may be declared before its values exist (``Preset.unpublished``): the published
study that will produce them is named, and selecting it is one clear error until then
(docs/decisions/0215-what-tuned-means-before-the-studies.md). May import: envs.errors.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from envs.errors import BenchError

__all__ = ["PAPER", "Preset", "preset_names", "preset_values"]

PAPER = "paper"  # every method's default preset: its Params defaults, recorded nowhere


@dataclass(frozen=True)
class Preset:
    """Parameter values of one named preset and where they come from."""

    values: Mapping[str, Any] = field(default_factory=dict)  # cell fields or Params fields
    source: str = ""  # the study (or measurement) the values come from
    pending: bool = False  # declared, its study not yet published: selecting it is an error

    @classmethod
    def unpublished(cls, study: str) -> Preset:
        """A preset whose values the published study ``study`` (a definition file) will give."""
        return cls(source=study, pending=True)


def preset_names(presets: Mapping[str, Preset]) -> list[str]:
    """The presets a method offers, ``paper`` first (unpublished ones marked)."""
    return [PAPER] + [f"{k} (no published study yet)" if p.pending else k
                      for k, p in sorted(presets.items()) if k != PAPER]


def preset_values(method: str, presets: Mapping[str, Preset], name: str) -> dict[str, Any]:
    """The values of preset ``name`` of ``method`` ({} for ``paper``); BenchError when the
    method lacks it or its study is not published yet."""
    if name == PAPER:
        return {}
    if name not in presets:
        raise BenchError(f"preset: method {method!r} has no preset {name!r} "
                         f"(its presets: {', '.join(preset_names(presets))})")
    preset = presets[name]
    if preset.pending:
        raise BenchError(f"preset: method {method!r} has no published study for preset {name!r} yet "
                         f"(its study: {preset.source}); use preset = \"paper\" or set the parameters")
    return dict(preset.values)
