"""What one trial computes: train a hierarchical cell in segments, evaluate after each.

A trial is a bench ``Cell`` (bench/design/cells.py) built from the study's ``TrialSettings`` (N,
p, layout and a smoke-scale budget by default), the sampled parameters (``ref_size``,
``search_radius``, optionally ``c_max``) and the trial's seed. The driver validates the
cell and ships plain data (a ``TrialSpec``) to a ``TrialWorker``. Each ``step()`` trains ``eval_every`` updates
through the
Method contract (``train_iteration``) and then evaluates greedily (``evaluate``) on a few
fixed chunks: the driver reports that value to Optuna and asks the pruner whether to go
on. The last step evaluates the full evaluation set; its value is the trial's objective.

Objective (single): success rate + 1e-3 * squash(team return per robot) with squash in
(0, 1), so the return only breaks ties between equal success rates and can never outweigh
one more robot reaching its goal. Multi-objective: (success rate, mean team return), both
maximized. Evaluation uses scenarios drawn from the *study* seed, identical for every
trial (common random numbers), while training uses the seed of the trial's replicate index
(studies/schedule.py ``replicate_seed``: replicate r of every point shares a seed).
"""
from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np
import torch
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from algorithms.base import Method
from algorithms.registry import method_class
from bench.design.cells import Cell
from bench.design.limits import limit, with_reasons
from envs.config import EnvConfig, Probability, format_validation_error
from envs.errors import BenchError
from studies.storage import Direction

Objectives = Literal["success", "success,return"]
TIE_BREAK = 1e-3  # weight of the squashed return in the single objective
RETURN_SCALE = 10.0  # team return per robot mapped through tanh(x / RETURN_SCALE)


class TrialSettings(BaseModel):
    """Fixed part of every trial of a study (the searched parameters come on top).

    Defaults are smoke scale: a few seconds per trial on one core.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    method: str = Field("hierarchical", description="registered method name or module:Class")
    n_robots: int = Field(8, ge=1, le=limit("n_robots"), description="team size N")
    loss_p: Probability = Field(0.2, description="inter-group message loss p")
    layout: str = Field("tiny", description="layout preset or map path")
    groups: int = Field(4, ge=1, le=limit("groups"), description="number of groups Z")
    horizon: int = Field(48, ge=1, le=limit("horizon"), description="episode length T")
    episodes: int = Field(48, ge=1, le=limit("episodes"), description="training episodes per trial")
    batch_episodes: int = Field(8, ge=1, description="episodes per update")
    eval_every: int = Field(2, ge=1, description="updates between intermediate evaluations")
    eval_episodes: int = Field(20, ge=1, le=limit("eval_episodes"),
        description="greedy episodes of the final evaluation")
    eval_chunk: int = Field(10, ge=1, description="episodes per evaluation chunk")
    report_chunks: int = Field(2, ge=1, description="chunks per intermediate evaluation (2 x 10 episodes:"
                               " fewer made pruning decisions noisy, issue #16)")
    objectives: Objectives = Field("success", description="single objective or (success, return)")
    params: dict[str, Any] = Field(default_factory=dict, description="fixed method hyperparameters")

    @classmethod
    def make(cls, **kwargs: Any) -> TrialSettings:
        try:
            return cls(**kwargs)
        except ValidationError as exc:
            text = format_validation_error("study settings", exc)
            raise BenchError(text + "".join(with_reasons(e, "") for e in exc.errors())) from None

    @property
    def iterations(self) -> int:
        """Training updates per trial: ceil(episodes / batch_episodes)."""
        return -(-self.episodes // self.batch_episodes)

    @property
    def multi_objective(self) -> bool:
        return self.objectives == "success,return"

    @property
    def directions(self) -> list[Direction]:
        return ["maximize", "maximize"] if self.multi_objective else ["maximize"]

    def cell(self, sampled: Mapping[str, Any], seed: int) -> Cell:
        """The validated bench cell a trial trains (BenchError naming a bad field): sampled
        cell fields (ref_size, search_radius, c_max) set the cell, other sampled names the
        method's hyperparameters."""
        fields = {k: v for k, v in sampled.items() if k in Cell.model_fields}
        params = {**self.params, **{k: v for k, v in sampled.items() if k not in fields},
                  "batch_episodes": self.batch_episodes, "eval_chunk": self.eval_chunk}
        return Cell.make(method=self.method, n_robots=self.n_robots, loss_p=self.loss_p,
                         groups=self.groups, layout=self.layout, episodes=self.episodes,
                         horizon=self.horizon, eval_episodes=self.eval_episodes, seed=seed,
                         params=params, **fields)

    def spec(self, sampled: Mapping[str, int], seed: int, eval_seed: int) -> TrialSpec:
        """Plain data a worker needs (it imports the method by path, not via the registry)."""
        cell = self.cell(sampled, seed)
        return TrialSpec(method_path=cell.method_path(), env=cell.to_env_config(),
                         params=cell.method_params().model_dump(mode="json"), seed=cell.seed,
                         eval_seed=eval_seed, cell_id=cell.cell_id, iterations=self.iterations,
                         eval_every=self.eval_every, eval_episodes=self.eval_episodes,
                         eval_chunk=self.eval_chunk, report_chunks=self.report_chunks,
                         objectives=self.objectives)


@dataclass(frozen=True)
class TrialSpec:
    """Everything a worker needs to run one trial (picklable plain data)."""

    method_path: str  # "module:Class"
    env: EnvConfig
    params: dict[str, Any]
    seed: int
    eval_seed: int
    cell_id: str
    iterations: int
    eval_every: int
    eval_episodes: int
    eval_chunk: int
    report_chunks: int
    objectives: str = "success"


def eval_seed(study_seed: int) -> int:
    """Seed of the evaluation scenarios shared by every trial of a study."""
    state = np.random.SeedSequence([int(study_seed), 0]).generate_state(1)
    return int(state[0] & 0x7FFFFFFF)


def squash_return(team_return: float, n_robots: int) -> float:
    """Team return per robot mapped monotonically into (0, 1)."""
    return 0.5 * (1.0 + math.tanh(team_return / max(n_robots, 1) / RETURN_SCALE))


def objective_values(success: float, team_return: float, objectives: str, n_robots: int) -> list[float]:
    """The value(s) told to Optuna for an evaluation with these means."""
    if objectives == "success,return":
        return [success, team_return]
    return [success + TIE_BREAK * squash_return(team_return, n_robots)]


@dataclass(frozen=True)
class Segment:
    """One intermediate result, streamed from the worker to the driver."""

    step: int  # training updates done so far (the pruner's step)
    episodes: int  # training episodes done so far
    success_rate: float  # mean greedy evaluation success rate
    team_return: float  # mean greedy evaluation team return
    values: tuple[float, ...]  # objective value(s) for Optuna
    eval_episodes: int  # episodes behind the means
    done: bool  # training finished; this was the final evaluation
    wall_s: float  # seconds spent on this segment
    # the safety filter's mean fallback and correction rates over the evaluation episodes
    # (algorithms/common/episodes.py; NaN for a method without a filter)
    fallback_rate: float = math.nan
    correction_rate: float = math.nan

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def filter_rates(rows: list[dict[str, Any]]) -> tuple[float, float]:
    """(fallback, correction) rates of the safety filter, each the mean over the evaluation
    episodes on which the filter ran (a non-NaN ``fallback_rate``: algorithms/common/episodes.py);
    (NaN, NaN) when it ran on none, as for a method without a filter (whose correction rate
    reads 0, since nothing changes its actions)."""
    ran = [r for r in rows if not math.isnan(float(r.get("fallback_rate", math.nan)))]
    if not ran:
        return math.nan, math.nan
    return (float(np.mean([r["fallback_rate"] for r in ran])),
            float(np.mean([r["correction_rate"] for r in ran])))


def load_method(path: str) -> type[Method]:
    """The class at ``module:Class`` (algorithms/registry.py resolves every method)."""
    return method_class(path)


class TrialWorker:
    """Trains and evaluates one trial segment by segment (runs in a Ray actor or inline)."""

    def __init__(self, spec: TrialSpec) -> None:
        torch.set_num_threads(1)
        self.spec = spec
        self.method = load_method(spec.method_path)(spec.env, spec.params, spec.seed)

    def step(self) -> Segment:
        """Train up to ``eval_every`` updates, then evaluate; ``done`` after the last update."""
        t0 = time.perf_counter()
        s, m = self.spec, self.method
        for _ in range(min(s.eval_every, s.iterations - m.iterations)):
            m.train_iteration()
        done = m.iterations >= s.iterations
        n_chunks = -(-s.eval_episodes // s.eval_chunk) if done else s.report_chunks
        rows = [row for chunk in range(n_chunks) for row in m.evaluate(chunk, seed=s.eval_seed)]
        if done:
            rows = rows[: s.eval_episodes]
        success = float(np.mean([r["success_rate"] for r in rows]))
        ret = float(np.mean([r["team_return"] for r in rows]))
        values = objective_values(success, ret, s.objectives, s.env.n_robots)
        fallback, correction = filter_rates(rows)
        return Segment(step=m.iterations, episodes=m.episodes_done, success_rate=success,
                       team_return=ret, values=tuple(values), eval_episodes=len(rows),
                       done=done, wall_s=time.perf_counter() - t0, fallback_rate=fallback,
                       correction_rate=correction)
