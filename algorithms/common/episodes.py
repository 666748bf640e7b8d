"""A batch of B episodes with its own seeded streams, and per-episode metrics.

Every method runs its episodes through ``EpisodeBatch`` (scenarios and loss streams drawn
from one ``numpy.random.Generator``) and records what its controller did each step in a
``Decision``; ``EpisodeStats`` turns the steps into the metric rows the store keeps
(SPEC 4: eval columns). Seeds: ``batch_rng(seed, stream, index)`` derives an independent
generator from the cell seed with ``SeedSequence``, so an episode chunk gives the same
numbers whichever worker runs it.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np

from envs.channel import Channel, open_channel
from envs.config import EnvConfig
from envs.core import StepResult, WarehouseCore
from envs.layouts import Layout, load_layout
from envs.scenarios import sample_scenarios
from envs.tasks import TaskStream

__all__ = ["EVAL_METRICS", "EVAL_STREAM", "MAPF_METRICS", "TRAIN_STREAM", "Decision", "EpisodeBatch", "EpisodeStats",
           "batch_rng"]

# The random streams of ``batch_rng``: training episodes, evaluation episodes.
TRAIN_STREAM, EVAL_STREAM = 0, 1


def batch_rng(seed: int, stream: int, index: int) -> np.random.Generator:
    """Generator for chunk ``index`` of stream ``stream`` (train/eval) of a cell seed."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(stream), int(index)]))


class EpisodeBatch:
    """B episodes on one layout: the core plus the generator that drew its scenarios.

    The environment owns the channel: a method opens it with ``open_channel`` right after
    construction, in a fixed order, and its draws come from ``rng``, so the whole batch is a
    pure function of (config, rng seed).
    """

    def __init__(self, config: EnvConfig, batch: int, rng: np.random.Generator,
                 layout: Layout | None = None) -> None:
        self.config = config
        self.rng = rng
        self.core = WarehouseCore(config, layout if layout is not None else load_layout(config.layout))
        starts, goals = sample_scenarios(self.core.layout, config.n_robots, batch, rng)
        self.starts, self.goals = np.asarray(starts), np.asarray(goals)  # (B, N) free-cell indices
        tasks = None  # lifelong: next goals from the batch's seed, no draw from rng
        if config.task == "lifelong":
            tasks = TaskStream.seeded(self.core.layout, config.n_robots, batch, rng)
        self.core.reset(starts, goals, tasks)

    def open_channel(self, level: str = "groups") -> Channel:
        """The environment's lossy channel of these B episodes, between groups or robots
        (``envs.channel.open_channel``), drawing from this batch's generator."""
        return open_channel(self.config, self.core.batch, self.rng, level)

    def scenario_hashes(self) -> list[str]:
        """Per episode, 16 hex digits of SHA-256 over its starts and goals (the ``scenario``
        eval column: rows of different execution modes with equal hashes ran one scenario)."""
        s = np.ascontiguousarray(self.starts, dtype=np.int64)
        g = np.ascontiguousarray(self.goals, dtype=np.int64)
        return [hashlib.sha256(s[b].tobytes() + g[b].tobytes()).hexdigest()[:16]
                for b in range(s.shape[0])]

    @property
    def running(self) -> bool:
        return not bool(self.core.ended.all())


@dataclass
class Decision:
    """What a controller decided at one step for B episodes (all arrays shaped (B,) or (B, N))."""

    actions: np.ndarray  # (B, N) executed controls U_t
    proposed: np.ndarray | None = None  # (B, N) controls proposed before the safety filter
    candidates: np.ndarray | None = None  # (B,) candidates examined, summed over groups
    filter_calls: np.ndarray | None = None  # (B,) group-steps that ran the filter
    fallbacks: np.ndarray | None = None  # (B,) group-steps that fell back to joint Wait
    pred_sq_err: np.ndarray | None = None  # (B,) summed squared error of predicted messages
    pred_count: np.ndarray | None = None  # (B,) number of lost messages predicted
    payload: np.ndarray | float = 0.0  # (B,) or scalar: scalars transmitted this step
    group_links: np.ndarray | None = None  # (B, Z', Z) bool: inter-group link z' -> z delivered
    robot_links: np.ndarray | None = None  # (B, N_send, N_recv) bool: robot-to-robot messages delivered

    def __post_init__(self) -> None:
        # ``choice(logits)`` gives a torch tensor; the environment and the stored rows take
        # NumPy, so a (B, N) CPU tensor of controls is taken as its NumPy array (same values).
        if not isinstance(self.actions, np.ndarray):
            self.actions = np.asarray(self.actions)


# The per-episode metric columns of every row ``EpisodeStats`` writes.
EVAL_METRICS = (
    "team_return", "success_rate", "collision_rate", "invalid_rate", "correction_rate",
    "mean_candidates", "fallback_rate", "predictor_error", "payload_scalars_per_step",
    "payload_dec_per_step", "steps",
)

# The metrics MAPF researchers read, as POGEMA defines them (docs/decisions/0212): CSR, sum of
# costs and makespan of one-shot episodes, throughput of lifelong ones (NaN where they do not
# apply). Added after the first committed stores: an older eval file reads them as NaN.
MAPF_METRICS = ("csr", "sum_of_costs", "makespan", "throughput")


@dataclass
class EpisodeStats:
    """Accumulates per-episode sums over steps for B episodes."""

    batch: int
    n_robots: int
    d_m: int = 3
    lifelong: bool = False
    sums: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        keys = ("ret", "coll", "invalid", "active", "corr", "cand", "calls", "fallback",
                "sq_err", "pred_n", "payload", "steps")
        self.sums = {k: np.zeros(self.batch, dtype=np.float64) for k in keys}
        self.success = np.zeros(self.batch, dtype=np.float64)
        self.goals = np.zeros(self.batch, dtype=np.float64)  # goals reached (throughput)
        self.arrival = np.full((self.batch, self.n_robots), -1.0)  # steps to first arrival, -1: none yet

    def add(self, running: np.ndarray, res: StepResult, dec: Decision) -> None:
        """Record one step; ``running`` (B,) marks episodes that were running before it."""
        s, run = self.sums, running.astype(np.float64)
        act = res.active
        s["ret"] += res.reward
        s["coll"] += (res.collision & act).sum(axis=1)
        s["invalid"] += res.invalid.sum(axis=1)
        s["active"] += act.sum(axis=1)
        s["steps"] += run
        reached = res.reached
        self.goals += reached.sum(axis=1)
        np.copyto(self.arrival, np.broadcast_to(s["steps"][:, None], reached.shape),
                  where=reached & (self.arrival < 0))
        if dec.proposed is not None:
            s["corr"] += ((dec.proposed != dec.actions) & act).sum(axis=1)
        for key, val in (("cand", dec.candidates), ("calls", dec.filter_calls),
                         ("fallback", dec.fallbacks), ("sq_err", dec.pred_sq_err),
                         ("pred_n", dec.pred_count)):
            if val is not None:
                s[key] += np.asarray(val, dtype=np.float64) * run
        s["payload"] += np.broadcast_to(np.asarray(dec.payload, dtype=np.float64), run.shape) * run

    def finish(self, done: np.ndarray) -> list[dict[str, float]]:
        """One row per episode; ``done`` (B, N) is the final completion mask."""
        s = self.sums
        steps = np.maximum(s["steps"], 1)
        active = np.maximum(s["active"], 1)
        calls = s["calls"]
        rows = []
        for b in range(self.batch):
            rows.append({
                "team_return": float(s["ret"][b]),
                "success_rate": float(done[b].mean()),
                "collision_rate": float(s["coll"][b] / active[b]),
                "invalid_rate": float(s["invalid"][b] / active[b]),
                "correction_rate": float(s["corr"][b] / active[b]),
                "mean_candidates": float(s["cand"][b] / calls[b]) if calls[b] else float("nan"),
                "fallback_rate": float(s["fallback"][b] / calls[b]) if calls[b] else float("nan"),
                "predictor_error": float(s["sq_err"][b] / s["pred_n"][b]) if s["pred_n"][b] else float("nan"),
                "payload_scalars_per_step": float(s["payload"][b] / steps[b]),
                "payload_dec_per_step": float(self.n_robots * (self.n_robots - 1) * self.d_m),
                "steps": int(s["steps"][b]),
                **self._mapf(b, done[b]),
            })
        return rows

    def _mapf(self, b: int, done: np.ndarray) -> dict[str, float]:
        """``MAPF_METRICS`` of episode ``b`` (POGEMA's definitions, docs/decisions/0212):
        a robot's cost is the number of steps until it first stood on its goal (0 if it
        started there), the episode's length if it never did; sum of costs and makespan are
        their sum and maximum, CSR is 1 when every robot arrived; throughput is goals
        reached per step over the episode."""
        nan = float("nan")
        steps = self.sums["steps"][b]
        if self.lifelong:
            return {"csr": nan, "sum_of_costs": nan, "makespan": nan,
                    "throughput": float(self.goals[b] / max(steps, 1.0))}
        cost = np.where(done, np.maximum(self.arrival[b], 0.0), steps)
        return {"csr": float(done.all()), "sum_of_costs": float(cost.sum()),
                "makespan": float(cost.max()) if cost.size else 0.0, "throughput": nan}
