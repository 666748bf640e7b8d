"""Validated environment configuration (pydantic): defaults live here, callers override."""
from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from envs.errors import BenchError

# A probability: the one range of the loss rate p, wherever a configuration takes one (the
# environment, a grid's cell, a study's fixed settings).
Probability = Annotated[float, Field(ge=0.0, le=1.0)]


class RewardWeights(BaseModel):
    """Positive weights of eq:reward. The paper gives no values; see docs/decisions/0005."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    q_p: float = Field(1.0, gt=0, description="progress: shortest-path distance reduction")
    q_g: float = Field(10.0, gt=0, description="first arrival at the goal")
    q_c: float = Field(2.0, gt=0, description="collision (involved in a conflict this step)")
    q_tau: float = Field(0.1, gt=0, description="per step while the task is unfinished")


def max_bursty_loss(burst_length: float) -> float:
    """The largest mean loss a Gilbert-Elliott chain with bad runs of ``burst_length`` steps
    on average can have: L / (L + 1), where P(Good -> Bad) = p / (L (1 - p)) reaches 1
    (every delivered step is followed by a loss). A larger p needs longer bursts,
    L >= p / (1 - p)."""
    return burst_length / (burst_length + 1.0)


def bursty_loss_error(loss_p: float, burst_length: float) -> str | None:
    """Why (loss_p, burst_length) is no Gilbert-Elliott channel, or None when it is one.
    p = 1 (never delivered) is a channel at any burst length."""
    if loss_p >= 1.0 or loss_p <= max_bursty_loss(burst_length) * (1.0 + 1e-12):
        return None
    return (f"mean loss {loss_p:g} is more than bursts of {burst_length:g} steps allow "
            f"(at most {max_bursty_loss(burst_length):.4g}: P(Good -> Bad) = p / (L (1 - p)) "
            f"would exceed 1); use bursts of at least {loss_p / (1.0 - loss_p):.4g} steps or a smaller loss")


LOSS_MODELS = ("bernoulli", "gilbert_elliott")  # i.i.d. per link and step; bursty two-state chain


def loss_error(loss_p: float, loss_model: str = "bernoulli",
               burst_length: float = 4.0) -> tuple[tuple[str, ...], str] | None:
    """The loss rule, checked once where a loss enters (``EnvConfig``, which every cell
    and study validates through, and ``bench matrix``'s --p, --loss-model and --burst):
    (the inputs at fault, why) when (loss_p, loss_model, burst_length) is no loss process,
    else None. ``LossProcess`` takes the values of a validated ``EnvConfig`` and does not
    check them again."""
    if not (math.isfinite(loss_p) and 0.0 <= loss_p <= 1.0):
        return ("loss_p",), "a loss probability must be in [0, 1]"
    if loss_model not in LOSS_MODELS:
        return ("loss_model",), f"unknown loss model; choose {' or '.join(LOSS_MODELS)}"
    if not (math.isfinite(burst_length) and burst_length >= 1.0):
        return ("burst_length",), "a mean burst length must be >= 1 step"
    why = bursty_loss_error(loss_p, burst_length) if loss_model == "gilbert_elliott" else None
    return (("loss_p", "burst_length"), why) if why is not None else None


def delay_error(delay: float, model: str, bound: int) -> str | None:
    """Why (delay, delay_model, delay_max) is no delay process, or None when it is one: a
    fixed delay is a whole number of steps within the bound; a geometric mean is below it."""
    if model == "fixed" and delay != int(delay):
        return f"delay={delay:g}: a fixed delay is a whole number of steps (or use delay_model='geometric')"
    if model == "fixed" and delay > bound:
        return f"delay={delay:g} exceeds delay_max={bound}"
    if model == "geometric" and delay > 0 and delay >= bound:
        return f"delay={delay:g}: a geometric mean delay must be below delay_max={bound}"
    return None


class EnvConfig(BaseModel):
    """Everything that defines a warehouse episode distribution and its channel."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    n_robots: int = Field(20, ge=1, le=10_000, description="team size N")
    layout: str = Field("wh20", description="preset name, MovingAI .map path or ASCII .txt path")
    groups: int = Field(
        4, ge=1, description="number of fixed groups Z (robot i in group i mod Z); default min(4, N)"
    )
    horizon: int = Field(500, ge=1, description="maximum episode length T")
    on_goal: Literal["remove", "stay"] = Field(
        "remove", description="completed robots leave the floor, or stay as obstacles and Wait"
    )
    task: Literal["one-shot", "lifelong"] = Field(
        "one-shot", description="one goal per robot (the paper), or a next goal on every arrival until the horizon"
    )
    loss_p: Probability = Field(0.2, description="mean inter-group message loss p")
    loss_model: Literal["bernoulli", "gilbert_elliott"] = Field(
        "bernoulli", description="i.i.d. loss per link and step, or bursty two-state loss"
    )
    burst_length: float = Field(
        4.0, ge=1.0, description="mean length of a loss burst (gilbert_elliott only), steps"
    )
    delay: float = Field(
        0.0, ge=0.0, description="mean message delay, steps (0: a delivered message arrives the step it is sent)"
    )
    delay_model: Literal["fixed", "geometric"] = Field(
        "fixed", description="every message delayed by exactly `delay` steps, or a geometric draw per message"
    )
    delay_max: int = Field(
        16, ge=0, description="bound on a message's delay, steps (geometric draws above it are cut to it)"
    )
    comm_graph: Literal["complete", "ring"] = Field(
        "complete", description="directed inter-group graph G: all pairs, or z-1 -> z <- z+1"
    )
    d_m: int = Field(3, ge=1, description="scalars per robot in a message (2 position + 1 control)")
    reward: RewardWeights = Field(default_factory=RewardWeights)

    @model_validator(mode="before")
    @classmethod
    def _default_groups(cls, data: object) -> object:
        """``groups`` left out means min(4, n_robots), so a team of 2 or 3 needs no override."""
        if isinstance(data, dict) and "groups" not in data:
            n = data.get("n_robots", 20)
            if type(n) is int and 1 <= n < 4:
                data = {**data, "groups": n}
        return data

    @model_validator(mode="after")
    def _groups_fit(self) -> EnvConfig:
        if self.groups > self.n_robots:
            raise ValueError(f"groups={self.groups} exceeds n_robots={self.n_robots}")
        found = loss_error(self.loss_p, self.loss_model, self.burst_length)
        if found is not None:
            names, loss_why = found
            raise ValueError(" with ".join(f"{n}={getattr(self, n):g}" for n in names) + f": {loss_why}")
        delay_why = delay_error(self.delay, self.delay_model, self.delay_max)
        if delay_why is not None:
            raise ValueError(delay_why)
        return self

    @classmethod
    def make(cls, **kwargs: object) -> EnvConfig:
        """Build a config, turning validation failures into one clear BenchError."""
        try:
            return cls(**kwargs)
        except ValidationError as exc:
            raise BenchError(format_validation_error("environment config", exc)) from None


def format_validation_error(what: str, exc: ValidationError) -> str:
    """One line naming each bad field and why."""
    parts = []
    for err in exc.errors():
        loc = ".".join(str(p) for p in err["loc"]) or "(config)"
        parts.append(f"{loc}: {err['msg']}")
    return f"invalid {what}: " + "; ".join(parts)
