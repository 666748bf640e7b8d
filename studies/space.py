"""The search space of a study: |R_z| (``ref_size``), L (``search_radius``), C_max (``c_max``).

The paper leaves the cardinality of the reference space open (Proposition 1: a smaller
|R_z| compresses more, ``log |R_z|`` bounds the inter-group information reaching the local
policy) and names the safety filter's radius L and budget C_max as a trade-off between
correction capability and search effort (Lemma 1, eq:safety_deviation). A study searches
the grid below; every dimension is categorical over integers so the L x |R_z| landscape
is a complete table and user overrides may pick any subset of values.

``c_max`` joins the space only on request: its default choices bracket Lemma 1's bound
``sum_{d<=L} C(n_z, d) (m-1)^d`` for a group of five robots (181 at L=2, 821 at L=3)
and include the paper's 500 (Sec. IV).
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

from optuna.distributions import BaseDistribution, CategoricalDistribution

from envs.errors import BenchError

REF_SIZES: tuple[int, ...] = (2, 4, 8, 16, 32)
SEARCH_RADII: tuple[int, ...] = (0, 1, 2, 3)
C_MAX_CHOICES: tuple[int, ...] = (50, 100, 250, 500, 1000)

#: name -> (default choices, smallest valid value)
PARAMETERS: dict[str, tuple[tuple[int, ...], int]] = {
    "ref_size": (REF_SIZES, 1),
    "search_radius": (SEARCH_RADII, 0),
    "c_max": (C_MAX_CHOICES, 1),
}

Space = dict[str, tuple[int, ...]]


def search_space(c_max: bool = False, overrides: Mapping[str, Iterable[int]] | None = None) -> Space:
    """The study's space: name -> sorted tuple of integer choices.

    ``ref_size`` in {2, 4, 8, 16, 32} and ``search_radius`` in {0, 1, 2, 3}, plus ``c_max``
    when ``c_max`` is true. ``overrides`` replaces the choices of named parameters (an
    override of ``c_max`` adds it to the space). Unknown names, empty or invalid ranges
    raise ``BenchError``.
    """
    space: Space = {"ref_size": REF_SIZES, "search_radius": SEARCH_RADII}
    if c_max:
        space["c_max"] = C_MAX_CHOICES
    for name, values in (overrides or {}).items():
        if name not in PARAMETERS:
            raise BenchError(
                f"unknown study parameter {name!r}; choose from {', '.join(PARAMETERS)}")
        space[name] = _validated(name, values)
    return {name: space[name] for name in PARAMETERS if name in space}


def _validated(name: str, values: Iterable[int]) -> tuple[int, ...]:
    try:
        vals = sorted({int(v) for v in values})
    except (TypeError, ValueError):
        raise BenchError(f"study parameter {name}: values must be integers, got {values!r}") from None
    if not vals:
        raise BenchError(f"study parameter {name}: empty range; give at least one value")
    low = PARAMETERS[name][1]
    if vals[0] < low:
        raise BenchError(f"study parameter {name}: values must be >= {low}, got {vals[0]}")
    return tuple(vals)


def parse_overrides(texts: Sequence[str]) -> dict[str, list[int]]:
    """Parse CLI overrides ``NAME=V1,V2,...`` or ``NAME=LOW..HIGH`` (inclusive) into lists.

    ``"search_radius=1..2"`` -> ``{"search_radius": [1, 2]}``; ``"ref_size="`` is an empty
    range and ``"ref_size=8..4"`` too: both raise ``BenchError``, as does a malformed item.
    """
    out: dict[str, list[int]] = {}
    for text in texts:
        name, sep, rhs = text.partition("=")
        name, rhs = name.strip(), rhs.strip()
        if not sep or not name:
            raise BenchError(f"study parameter override {text!r}: expected NAME=V1,V2 or NAME=LOW..HIGH")
        if name not in PARAMETERS:
            raise BenchError(
                f"unknown study parameter {name!r}; choose from {', '.join(PARAMETERS)}")
        try:
            if ".." in rhs:
                lo, hi = (int(x) for x in rhs.split("..", 1))
                values = list(range(lo, hi + 1))
            else:
                values = [int(x) for x in rhs.split(",") if x.strip()]
        except ValueError:
            raise BenchError(f"study parameter {name}: cannot parse {rhs!r} as integers") from None
        if not values:
            raise BenchError(f"study parameter {name}: empty range {rhs!r}; give at least one value")
        out[name] = values
    return out


def distributions(space: Mapping[str, Sequence[int]]) -> dict[str, BaseDistribution]:
    """Optuna distributions for ``study.ask(fixed_distributions=...)`` (all categorical)."""
    return {name: CategoricalDistribution(list(choices)) for name, choices in space.items()}


def space_size(space: Mapping[str, Sequence[int]]) -> int:
    """Number of distinct configurations (20 for the default L x |R_z| grid)."""
    size = 1
    for choices in space.values():
        size *= len(choices)
    return size
