"""One experiment cell: a frozen, validated config with a stable id (SPEC 4 "Cell").

A cell fixes everything that determines its numbers: the method and its hyperparameters,
the team size N, the loss probability p, the seed, the grouping Z, the safety-filter
settings (|R_z|, L, C_max), the layout, the budgets and the evaluation temperatures
(every learned cell is evaluated in argmax, sample and sample@T for each T of
``eval_temperatures``: ``Cell.execution_modes``). ``cell_id`` is the first 12 hex
digits of the SHA-256 of the canonical JSON (sorted keys, no spaces) of all fields, so
the same config always maps to the same rows of the store, whatever grid it came from.
A named ``preset`` of the method's parameters (algorithms/presets.py) fills what the cell
leaves unset and is recorded with the values; ``paper``, the default, is left out of the
canonical JSON, so every cell id from before presets is unchanged.
"""
from __future__ import annotations

import hashlib
import json
from functools import cached_property
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from algorithms.base import MethodParams
from algorithms.common.execution import DEFAULT_TEMPERATURES, check_temperatures
from algorithms.presets import PAPER, preset_values
from algorithms.registry import method_class, method_target
from bench.design.limits import limit, with_reasons
from envs.config import EnvConfig, Probability, format_validation_error
from envs.errors import BenchError
from envs.layouts import load_layout, preset_for
from envs.scenarios import main_region

# Largest horizon T a cell may ask for: 20x the paper's 500 steps (Sec. IV). Rollout arrays
# grow with T x N x batch, so T = 10**12 would fail at run time with MemoryError instead.
# Every count has such a bound, with its reason (bench/design/limits.py).
MAX_HORIZON = limit("horizon")

# Fields added after the first committed stores: left out of the canonical JSON while at
# their default, so every cell that does not set them keeps its id (docs/decisions/0209).
LATER_FIELDS = ("delay", "delay_model", "task", "preset")

# Cell fields handed to a method when (and only when) its Params declares them.
SHARED_PARAM_FIELDS = ("ref_size", "search_radius", "c_max", "safety_filter")


class Cell(BaseModel):
    """A frozen experiment config; every field is validated, ``cell_id`` hashes them all."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    # strict=True on numbers and flags: `n_robots = true` or `horizon = 2.5` is an error, not 1
    # or 2 (a number is a number, a flag is a flag); an int is still accepted for a float.
    method: str = Field(description="registered method name or module:Class (algorithms/registry.py)")
    n_robots: int = Field(ge=1, le=limit("n_robots"), strict=True, description="team size N")
    loss_p: Probability = Field(strict=True, description="inter-group message loss probability p")
    seed: int = Field(0, ge=0, lt=2**31, strict=True, description="root of every random stream of the cell")
    groups: int = Field(4, ge=1, le=limit("groups"), strict=True, description="number of fixed groups Z")
    ref_size: int = Field(8, ge=1, le=limit("ref_size"), strict=True, description="abstract references per group |R_z|")
    search_radius: int = Field(2, ge=0, le=limit("search_radius"), strict=True,
        description="safety-filter search radius L")
    c_max: int = Field(500, ge=1, le=limit("c_max"), strict=True, description="safety-filter candidate budget C_max")
    safety_filter: bool = Field(
        False, strict=True, description="safety filter on (default: the method's safety_filter_default)"
    )
    layout: str = Field("auto", description="'auto' (preset sized for N), a preset or a .map path")
    episodes: int = Field(2000, ge=0, le=limit("episodes"), strict=True,
                          description="training episodes (0: evaluate the initialization)")
    horizon: int = Field(500, ge=1, le=MAX_HORIZON, strict=True, description="maximum episode length T")
    eval_episodes: int = Field(100, ge=1, le=limit("eval_episodes"), strict=True,
        description="evaluation episodes (per execution mode)")
    eval_temperatures: tuple[float, ...] = Field(
        DEFAULT_TEMPERATURES,
        description="temperatures T != 1 of the tempered evaluation modes sample@T (learned methods; "
                    "argmax and sample are always evaluated)")
    on_goal: Literal["remove", "stay"] = Field("remove", description="robots at their goal leave / stay")
    loss_model: Literal["bernoulli", "gilbert_elliott"] = Field("bernoulli", description="loss process")
    task: Literal["one-shot", "lifelong"] = Field(
        "one-shot", description="one goal per robot (the paper) or lifelong tasks to the horizon")
    delay: float = Field(0.0, ge=0.0, strict=True,
                         description="mean message delay in steps (0: none; beyond the paper)")
    delay_model: Literal["fixed", "geometric"] = Field("fixed", description="fixed delay or geometric per message")
    params: dict[str, Any] = Field(default_factory=dict, description="method hyperparameter overrides")
    preset: str = Field(PAPER, description="named preset of the method's parameters (Method.presets): its "
                        "values fill the fields and params the cell leaves unset; 'paper' (the defaults) "
                        "is not recorded, so a paper cell's id is the one it always had")

    @model_validator(mode="before")
    @classmethod
    def _resolve_defaults(cls, data: Any) -> Any:
        """'auto' layout -> the preset sized for N; unset safety_filter -> per-method default."""
        if not isinstance(data, dict):
            return data
        data = _apply_preset(dict(data))
        if data.get("safety_filter") is None and isinstance(data.get("method"), str):
            try:  # the method's declared default (an unknown method fails in _known_method)
                data["safety_filter"] = method_class(data["method"]).safety_filter_default
            except BenchError:
                data["safety_filter"] = False
        n = data.get("n_robots")
        if data.get("layout", "auto") == "auto" and isinstance(n, int) and not isinstance(n, bool):
            data["layout"] = preset_for(n)
        return data

    @field_validator("method")
    @classmethod
    def _known_method(cls, name: str) -> str:
        try:
            method_class(name)
        except BenchError as exc:
            raise ValueError(str(exc).removeprefix("method ")) from None
        return name

    @field_validator("eval_temperatures")
    @classmethod
    def _temperatures(cls, temps: tuple[float, ...]) -> tuple[float, ...]:
        return check_temperatures(temps)

    @model_validator(mode="after")
    def _check(self) -> Cell:
        try:  # the environment's rules (groups, delay, the loss rule), checked once: by EnvConfig
            self._env_config()
        except ValidationError as exc:
            raise ValueError("; ".join(str(e["msg"]).removeprefix("Value error, ") for e in exc.errors())) from None
        clash = sorted(set(self.params) & (set(SHARED_PARAM_FIELDS) | set(type(self).model_fields)))
        if clash:
            raise ValueError(f"params.{clash[0]}: set it as the cell field {clash[0]!r}, not in params")
        try:
            json.dumps(self.params, sort_keys=True, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"params: not plain JSON data ({exc})") from None
        return self

    @classmethod
    def make(cls, **fields: Any) -> Cell:
        """Build and validate a cell (method params included); one BenchError naming the field."""
        try:
            cell = cls(**fields)
        except ValidationError as exc:
            raise BenchError(_one_line("cell", exc)) from None
        cell.validate_runtime()
        return cell

    def validate_runtime(self) -> None:
        """Checks that need the layout file and the method class (BenchError naming the field)."""
        try:
            layout = load_layout(self.layout)
        except BenchError as exc:
            raise BenchError(f"invalid cell: layout: {exc}") from None
        try:
            region = len(main_region(layout))
        except BenchError as exc:  # no free cell at all
            raise BenchError(f"invalid cell: layout: {exc}; {self.n_robots} robots need at least "
                             f"{self.n_robots + (self.n_robots == 1)} connected free cells") from None
        if self.n_robots > region or (self.n_robots == region == 1):
            raise BenchError(
                f"invalid cell: n_robots: {self.n_robots} robots do not fit layout "
                f"{self.layout!r} ({region} connected free cells)"
            )
        self.method_params()

    # ----------------------------------------------------------------- identity
    def canonical_json(self) -> str:
        """Every field as sorted JSON; a later field (LATER_FIELDS) only when not at its default."""
        data = self.model_dump(mode="json")
        for name in LATER_FIELDS:
            if data[name] == type(self).model_fields[name].default:
                del data[name]
        return json.dumps(data, sort_keys=True, separators=(",", ":"))

    @cached_property
    def cell_id(self) -> str:
        return hashlib.sha256(self.canonical_json().encode()).hexdigest()[:12]

    def __hash__(self) -> int:
        return hash(self.cell_id)

    # ----------------------------------------------------------- what it runs
    def _env_config(self) -> EnvConfig:
        """The cell's environment; a ``ValidationError`` when the environment refuses it."""
        return EnvConfig(
            n_robots=self.n_robots, layout=self.layout, groups=self.groups, horizon=self.horizon,
            on_goal=self.on_goal, loss_p=self.loss_p, loss_model=self.loss_model,
            delay=self.delay, delay_model=self.delay_model, task=self.task,
        )

    def to_env_config(self) -> EnvConfig:
        try:
            return self._env_config()
        except ValidationError as exc:
            raise BenchError(format_validation_error("environment config", exc)) from None

    def method_params(self) -> MethodParams:
        """The method's validated Params: ``params`` plus the shared cell fields it declares."""
        try:
            cls = method_class(self.method)
        except ImportError as exc:
            raise BenchError(f"method {self.method!r} cannot be imported: {exc}") from None
        fields = cls.Params.model_fields
        merged = {k: getattr(self, k) for k in SHARED_PARAM_FIELDS if k in fields}
        merged.update(self.params)
        try:
            return cls.Params(**merged)
        except ValidationError as exc:
            raise BenchError(_one_line(f"cell params ({self.method})", exc)) from None

    def execution_modes(self) -> tuple[str, ...]:
        """Evaluation modes of the cell, in order: argmax, sample, sample@T (learned), or
        planner (a planner such as PIBT)."""
        try:
            cls = method_class(self.method)
        except ImportError as exc:
            raise BenchError(f"method {self.method!r} cannot be imported: {exc}") from None
        return cls.execution_modes(self.eval_temperatures)

    def stackable(self) -> bool:
        """Whether ``bench run --stack-seeds`` trains this cell with its other seeds
        (``Method.stackable`` of its method and parameters)."""
        return bool(method_class(self.method).stackable(self.method_params().model_dump(mode="json")))

    def method_path(self) -> str:
        """'module:Class' of the method (what workers import; algorithms/registry.py)."""
        return method_target(self.method)

    def config_columns(self) -> dict[str, Any]:
        """The config columns of cells.parquet (bench/store/schema.py CELLS_SCHEMA)."""
        return {
            "cell_id": self.cell_id, "method": self.method, "n_robots": self.n_robots,
            "loss_p": self.loss_p, "seed": self.seed, "groups": self.groups,
            "ref_size": self.ref_size, "search_radius": self.search_radius, "c_max": self.c_max,
            "safety_filter": self.safety_filter, "layout": self.layout, "episodes": self.episodes,
            "horizon": self.horizon, "eval_episodes": self.eval_episodes, "on_goal": self.on_goal,
            "loss_model": self.loss_model, "executions": ",".join(self.execution_modes()),
            "params_json": json.dumps(self.method_params().model_dump(mode="json"), sort_keys=True),
            "config_json": self.canonical_json(),
        }

    @classmethod
    def from_json(cls, text: str) -> Cell:
        try:
            return cls.make(**json.loads(text))
        except json.JSONDecodeError as exc:
            raise BenchError(f"invalid cell JSON: {exc}") from None


def _apply_preset(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` with the values of its ``preset`` (algorithms/presets.py) filled in where unset:
    cell fields the method declares as cell fields, the rest under ``params``. A preset the
    method lacks, or one not published yet, is a ValueError naming the preset."""
    name, method = data.get("preset", PAPER), data.get("method")
    if name == PAPER or not isinstance(name, str) or not isinstance(method, str):
        return data  # the field's own validation reports a non-string preset
    try:
        values = preset_values(method, method_class(method).presets, name)
    except BenchError as exc:  # an unknown method is reported by _known_method
        if str(exc).startswith("preset:"):
            raise ValueError(str(exc)) from None
        return data
    params = data.get("params", {})
    if not isinstance(params, dict):
        return data  # the field's own validation reports it
    params = dict(params)
    for key, value in values.items():
        if key in SHARED_PARAM_FIELDS:
            data.setdefault(key, value)
        else:
            params.setdefault(key, value)
    data["params"] = params
    return data


def _one_line(what: str, exc: ValidationError) -> str:
    """'invalid cell: n_robots: Input should be ...' (model-level errors name their field)."""
    parts = []
    for err in exc.errors():
        loc = ".".join(str(p) for p in err["loc"])
        msg = with_reasons(err, str(err["msg"]).removeprefix("Value error, "))
        parts.append(f"{loc}: {msg}" if loc else msg)
    return f"invalid {what}: " + "; ".join(parts)
