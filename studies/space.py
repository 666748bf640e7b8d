"""The search space of a study: the paper's |R_z| x L (x C_max), or any declared
hyperparameter of any learned method.

**The paper's study** (the default for a method whose parameters hold ``ref_size`` and
``search_radius``): the paper leaves the cardinality of the reference space open
(Proposition 1: a smaller |R_z| compresses more, ``log |R_z|`` bounds the inter-group
information reaching the local policy) and names the safety filter's radius L and budget
C_max as a trade-off between correction capability and search effort (Lemma 1,
eq:safety_deviation). Every dimension is categorical over integers so the L x |R_z|
landscape is a complete table and user overrides may pick any subset of values.
``c_max`` joins the space only on request: its default choices bracket Lemma 1's bound
``sum_{d<=L} C(n_z, d) (m-1)^d`` for a group of five robots (181 at L=2, 821 at L=3)
and include the paper's 500 (Sec. IV).

**Any method** (``bench tune --method M --param NAME=VALUES``): NAME is one of the cell
fields above or any field of M's ``Params`` (``bench methods M`` lists them) except the
budget the protocol fixes for every method (``batch_episodes``, ``eval_chunk``); values
are parsed by the field's type (integers, floats, true/false, strings) and each is
validated by M's own ``Params`` (its bounds, its message). Every method is tuned by the
same protocol: the same settings, replicate seeds, budget and pruning rule
(docs/studies.md, "The same tuning budget").
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from optuna.distributions import BaseDistribution, CategoricalDistribution
from pydantic import ValidationError

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

# Fixed by the protocol (studies/objective.py TrialSettings), the same for every method.
PROTOCOL_FIELDS = ("batch_episodes", "eval_chunk")

Value = int | float | bool | str
Space = dict[str, tuple[Value, ...]]


def plain(value: Any) -> Value:
    """A stored parameter value as plain Python (numpy scalars and pandas' Int64 unwrapped)."""
    return value.item() if hasattr(value, "item") else value


def ordered(names: Iterable[str]) -> list[str]:
    """Parameter names in a stable order: the paper's (``PARAMETERS``) first, others sorted."""
    names = set(names)
    return [p for p in PARAMETERS if p in names] + sorted(names - set(PARAMETERS))


def has_paper_space(method: str) -> bool:
    """Whether ``method`` declares the paper study's parameters (|R_z| and L)."""
    from algorithms.registry import method_class

    fields = method_class(method).Params.model_fields
    return "ref_size" in fields and "search_radius" in fields


def method_space(method: str, overrides: Mapping[str, Sequence[str]]) -> Space:
    """The space of a study of any ``method``: NAME -> sorted choices parsed from the
    strings of ``overrides`` by the type of NAME in the method's ``Params`` and validated
    by it. BenchError naming the parameter for an unknown name, a protocol field, an empty
    or unparsable value list or a value the method refuses."""
    from algorithms.registry import method_class

    cls = method_class(method)
    if not cls.learned:
        raise BenchError(f"method {method!r} is a planner: it learns nothing to tune")
    fields = cls.Params.model_fields
    space: Space = {}
    for name, texts in overrides.items():
        if name in PROTOCOL_FIELDS:
            raise BenchError(f"study parameter {name}: part of the tuning budget, which the protocol "
                             "fixes to the same value for every method (docs/studies.md)")
        if name not in fields:
            known = ", ".join(n for n in fields if n not in PROTOCOL_FIELDS)
            raise BenchError(f"unknown study parameter {name!r} for method {method}; choose from {known}")
        values = [v for t in texts for v in _parse_all(name, fields[name].annotation, t)]
        if not values:
            raise BenchError(f"study parameter {name}: empty range; give at least one value")
        for v in values:
            try:
                cls.Params.model_validate({name: v})
            except ValidationError as exc:
                err = exc.errors()[0]
                raise BenchError(f"study parameter {name}: {v!r}: {err['msg']}") from None
        space[name] = tuple(sorted(set(values), key=lambda v: (str(type(v)), v)))
    if not space:
        raise BenchError(f"method {method!r}: give the parameters to tune with --param NAME=VALUES "
                         f"(`bench methods {method}` lists them)")
    return {name: space[name] for name in ordered(space)}


def _parse_all(name: str, annotation: Any, text: str) -> list[Value]:
    """One value string, or an inclusive ``LOW..HIGH`` range of an integer parameter."""
    kinds = set(getattr(annotation, "__args__", ())) or {annotation}
    if ".." in text and int in kinds and float not in kinds:
        lo, _, hi = text.partition("..")
        return list(range(int(_parse(name, annotation, lo)), int(_parse(name, annotation, hi)) + 1))
    return [_parse(name, annotation, text)]


def _parse(name: str, annotation: Any, text: str) -> Value:
    kinds = set(getattr(annotation, "__args__", ())) or {annotation}
    t = text.strip()
    try:
        if bool in kinds:
            if t.lower() not in ("true", "false"):
                raise ValueError(t)
            return t.lower() == "true"
        if int in kinds and float not in kinds:
            return int(t)
        if float in kinds:
            return float(t)
    except ValueError:
        raise BenchError(f"study parameter {name}: cannot parse {t!r} as "
                         f"{'true/false' if bool in kinds else 'a number'}") from None
    return t


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


def split_overrides(texts: Sequence[str]) -> dict[str, list[str]]:
    """CLI overrides ``NAME=V1,V2,...`` -> NAME -> the value strings (``LOW..HIGH`` kept
    as one string); BenchError for an item without ``NAME=``."""
    out: dict[str, list[str]] = {}
    for text in texts:
        name, sep, rhs = text.partition("=")
        name, rhs = name.strip(), rhs.strip()
        if not sep or not name:
            raise BenchError(f"study parameter override {text!r}: expected NAME=V1,V2 or NAME=LOW..HIGH")
        out[name] = [x.strip() for x in rhs.split(",") if x.strip()]
    return out


def parse_overrides(texts: Sequence[str]) -> dict[str, list[int]]:
    """Parse CLI overrides of the paper's study ``NAME=V1,V2,...`` or ``NAME=LOW..HIGH``
    (inclusive) into lists.

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
                f"unknown study parameter {name!r}; choose from {', '.join(PARAMETERS)} "
                "(or tune any hyperparameter of a method: --method M --param NAME=VALUES)")
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


def distributions(space: Mapping[str, Sequence[Value]]) -> dict[str, BaseDistribution]:
    """Optuna distributions for ``study.ask(fixed_distributions=...)`` (all categorical)."""
    return {name: CategoricalDistribution(list(choices)) for name, choices in space.items()}


def space_size(space: Mapping[str, Sequence[Value]]) -> int:
    """Number of distinct configurations (20 for the default L x |R_z| grid)."""
    size = 1
    for choices in space.values():
        size *= len(choices)
    return size
