"""The vectorized core agrees exactly with the per-robot reference (tests/envs/reference_core.py).

Random small layouts (often crowded, so conflicts, cascades and rotations are common),
random scenarios (a robot may start on its goal), B > 1 episodes ending at different
times, both ``on_goal`` modes, and action sequences mixing random moves with greedy ones
(greedy robots reach goals, so terminations happen). Reward weights are dyadic so every
sum is exact in float64 and the comparison can be ``==``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from envs.config import EnvConfig
from envs.core import WarehouseCore
from envs.layouts import Layout
from envs.scenarios import main_region
from tests.envs.reference_core import MOVES, ReferenceCore

DYADIC = [0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 8.0]


@dataclass
class Case:
    obstacles: np.ndarray  # (H, W) bool
    starts: np.ndarray  # (B, N) cell indices
    goals: np.ndarray  # (B, N) cell indices
    on_goal: str
    horizon: int
    steps: int
    weights: tuple[float, float, float, float]
    greedy: float
    seed: int


def make_case(rng: np.random.Generator, h: int, w: int, density: float, crowd: float,
              batch: int, on_goal: str, horizon: int, steps: int,
              weights: tuple[float, float, float, float], greedy: float, seed: int) -> Case | None:
    obstacles = rng.random((h, w)) < density
    if obstacles.all():
        return None
    layout = Layout("case", obstacles)
    region = main_region(layout)
    n = max(1, min(len(region), 12, int(round(crowd * len(region)))))
    starts = np.stack([rng.choice(region, n, replace=False) for _ in range(batch)])
    goals = np.stack([rng.choice(region, n, replace=False) for _ in range(batch)])
    return Case(obstacles, starts, goals, on_goal, horizon, steps, weights, greedy, seed)


@st.composite
def cases(draw: st.DrawFn) -> Case:
    seed = draw(st.integers(0, 2**31 - 1))
    case = make_case(
        np.random.default_rng(seed),
        h=draw(st.integers(1, 6)), w=draw(st.integers(2, 7)),
        density=draw(st.sampled_from([0.0, 0.15, 0.3])),
        crowd=draw(st.sampled_from([0.2, 0.5, 0.8, 1.0])),
        batch=draw(st.integers(1, 3)),
        on_goal=draw(st.sampled_from(["remove", "stay"])),
        horizon=draw(st.integers(1, 14)), steps=draw(st.integers(1, 16)),
        weights=tuple(draw(st.sampled_from(DYADIC)) for _ in range(4)),
        greedy=draw(st.sampled_from([0.0, 0.5, 0.9])), seed=seed,
    )
    if case is None:
        draw(st.nothing())  # layouts without a free cell are rejected
    return case


def greedy_or_random(ref: ReferenceCore, rng: np.random.Generator, greedy: float) -> list[list[int]]:
    """Per episode and robot: a move that gets closer to the goal (p = greedy) or any action."""
    out = []
    for ep in ref.episodes:
        acts = []
        for pos, goal in zip(ep.pos, ep.goal, strict=True):
            a = int(rng.integers(5))
            if rng.random() < greedy:
                best = []
                for u, (dr, dc) in MOVES.items():
                    cell = (pos[0] + dr, pos[1] + dc)
                    if ref.free(cell) and ref.distance(cell, goal) < ref.distance(pos, goal):
                        best.append(u)
                if best:
                    a = best[int(rng.integers(len(best)))]
            acts.append(a)
        out.append(acts)
    return out


def run_both(case: Case) -> dict[str, int]:
    """Step core and reference side by side, asserting equality; return event counts."""
    layout = Layout("case", case.obstacles)
    n = case.starts.shape[1]
    q_p, q_g, q_c, q_tau = case.weights
    config = EnvConfig.make(
        n_robots=n, groups=1, horizon=case.horizon, on_goal=case.on_goal,
        reward=dict(q_p=q_p, q_g=q_g, q_c=q_c, q_tau=q_tau),
    )
    core = WarehouseCore(config, layout=layout)
    core.reset(case.starts, case.goals)
    ref = ReferenceCore(case.obstacles.tolist(), case.horizon, case.on_goal, case.weights)
    rc = layout.cells
    ref.reset(
        [[tuple(map(int, rc[c])) for c in row] for row in case.starts],
        [[tuple(map(int, rc[c])) for c in row] for row in case.goals],
    )
    rng = np.random.default_rng(case.seed + 1)
    seen = dict(collision=0, cascade=0, invalid=0, terminated=0, truncated=0, reached=0)
    for t in range(case.steps):
        actions = greedy_or_random(ref, rng, case.greedy)
        got = core.step(np.array(actions, dtype=np.int64))
        want = ref.step(actions)
        for b, w in enumerate(want):
            where = f"step {t}, episode {b}"
            assert [tuple(map(int, rc[c])) for c in core.pos[b]] == w.pos, where
            assert got.collision[b].tolist() == w.collision, where
            assert got.invalid[b].tolist() == w.invalid, where
            assert got.reached[b].tolist() == w.reached, where
            assert got.active[b].tolist() == w.active, where
            assert got.progress[b].tolist() == w.progress, where
            assert got.goal_bonus[b].tolist() == w.goal_bonus, where
            assert got.collision_penalty[b].tolist() == w.collision_penalty, where
            assert got.time_penalty[b].tolist() == w.time_penalty, where
            assert float(got.reward[b]) == w.reward, where
            assert bool(got.terminated[b]) == w.terminated, where
            assert bool(got.truncated[b]) == w.truncated, where
            assert core.done[b].tolist() == ref.episodes[b].done, where
            assert bool(core.ended[b]) == ref.episodes[b].ended, where
            seen["collision"] += sum(w.collision)
            seen["cascade"] += w.rounds > 1
            seen["invalid"] += sum(w.invalid)
            seen["terminated"] += w.terminated
            seen["truncated"] += w.truncated
            seen["reached"] += sum(w.reached)
    return seen


@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(cases())
def test_vectorized_core_matches_per_robot_reference(case: Case) -> None:
    run_both(case)


def test_reference_comparison_exercises_every_rule() -> None:
    """Fixed seeds through the same comparison see collisions, cascades, invalid moves,
    arrivals, terminations and truncations, so the property test above is not vacuous."""
    totals = dict.fromkeys(["collision", "cascade", "invalid", "terminated", "truncated", "reached"], 0)
    for seed in range(40):
        rng = np.random.default_rng(seed)
        case = make_case(
            rng, h=4, w=5, density=0.15, crowd=[0.3, 0.6, 1.0][seed % 3], batch=3,
            on_goal=["remove", "stay"][seed % 2], horizon=12, steps=14,
            weights=(1.0, 8.0, 2.0, 0.25), greedy=[0.5, 0.9][seed % 2], seed=seed,
        )
        assert case is not None
        for k, v in run_both(case).items():
            totals[k] += v
    assert all(v > 0 for v in totals.values()), totals
