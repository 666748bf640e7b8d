"""The observer hook of the Method contract: what an observer sees of every step.

``Method.run(batch, choice, observer)`` and ``Method.evaluate(..., observer=...)`` call
``observer(record)`` once per environment step of the batch, after the step, with a
``StepRecord`` of B episodes: positions before and after, the controls proposed and
executed, the messages delivered, and the safety filter's decisions. Every method gives
the same fields (``step_record`` builds them from the method's ``Decision``); a method
without messages or without a filter reports empty link arrays and no corrections.
Observing changes nothing: the record holds copies, no random draw is made for it.

May import: envs, algorithms.common.episodes.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from algorithms.common.episodes import Decision
from envs.core import StepResult, WarehouseCore

__all__ = ["Observer", "Snapshot", "StepRecord", "step_record"]


@dataclass(frozen=True)
class Snapshot:
    """Robot state of B episodes at one instant, (B, N) arrays (copies)."""

    pos: np.ndarray  # free-cell index of every robot
    done: np.ndarray  # bool, task completed
    on_floor: np.ndarray  # bool, occupies its cell (False once removed at its goal)

    @classmethod
    def of(cls, core: WarehouseCore) -> Snapshot:
        return cls(core.pos.copy(), core.done.copy(), core.occupying.copy())


@dataclass(frozen=True)
class StepRecord:
    """One step of B episodes as an observer sees it (B episodes, N robots, Z groups).

    ``group_links`` is (B, Z', Z), True where group z' delivered its message to group z
    this step (shape (B, 0, 0) for a method without a group channel); ``robot_links``
    (B, N_send, N_recv) the same between robots ((B, 0, 0) without robot messages).
    ``has_proposals`` says whether the method reported its proposals (``Decision.proposed``;
    a method with a safety filter does); without them ``proposed`` equals ``actions`` and
    nothing is corrected. Arrays are copies: an observer may keep them.
    """

    t: int  # index of the step (0 for the first)
    running: np.ndarray  # (B,) bool, episodes running before the step
    goal: np.ndarray  # (B, N) goal cell of every robot
    before: Snapshot  # robots before the step
    after: Snapshot  # robots after the step
    proposed: np.ndarray  # (B, N) controls proposed (before the safety filter)
    actions: np.ndarray  # (B, N) controls executed
    has_proposals: bool
    corrected: np.ndarray  # (B, N) bool, the filter changed the control of an active robot
    fallbacks: np.ndarray  # (B,) group-steps that fell back (0 without a filter)
    candidates: np.ndarray  # (B,) candidate joint controls examined (0 without a filter)
    group_links: np.ndarray  # (B, Z', Z) bool
    robot_links: np.ndarray  # (B, N_send, N_recv) bool
    result: StepResult  # the environment's step result (collisions, rewards, active robot-steps)


Observer = Callable[[StepRecord], None]


def _links(links: np.ndarray | None, batch: int) -> np.ndarray:
    return np.zeros((batch, 0, 0), bool) if links is None else np.array(links, dtype=bool)


def _per_episode(values: np.ndarray | None, batch: int) -> np.ndarray:
    return np.zeros(batch) if values is None else np.array(values, dtype=np.float64)


def step_record(t: int, running: np.ndarray, before: Snapshot, dec: Decision, res: StepResult,
                core: WarehouseCore) -> StepRecord:
    """The record of step ``t`` from the method's decision and the step's result."""
    b = core.pos.shape[0]
    actions = np.array(dec.actions)
    proposed = actions.copy() if dec.proposed is None else np.array(dec.proposed)
    return StepRecord(
        t=t, running=running.copy(), goal=core.goal.copy(), before=before, after=Snapshot.of(core),
        proposed=proposed, actions=actions, has_proposals=dec.proposed is not None,
        corrected=(proposed != actions) & res.active,
        fallbacks=_per_episode(dec.fallbacks, b), candidates=_per_episode(dec.candidates, b),
        group_links=_links(dec.group_links, b), robot_links=_links(dec.robot_links, b), result=res)
