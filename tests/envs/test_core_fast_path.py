"""``WarehouseCore.step`` (fewer array passes for the common cases) against the plain
formulas it replaced (``PlainCore``, kept verbatim in tests/envs/plain_paths.py): every
returned array and the state after each step are the same bit for bit, with the default
(non-dyadic) reward weights, B = 1 and B > 1, both ``on_goal`` modes, episodes ending at
different times and robots leaving.

Runtime: about 1 s.
"""
from __future__ import annotations

import copy
from dataclasses import fields

import numpy as np
import pytest

from envs.actions import N_ACTIONS
from envs.config import EnvConfig
from envs.core import StepResult, WarehouseCore
from envs.layouts import preset
from envs.scenarios import sample_scenarios
from tests.envs.plain_paths import PlainCore

STATE = ("pos", "dist", "done", "ended", "prev_actions", "t")


@pytest.mark.parametrize("on_goal", ["remove", "stay"])
@pytest.mark.parametrize("batch", [1, 5])
@pytest.mark.parametrize("layout_name,n", [("wh20", 20), ("tiny", 8)])
def test_step__equals_the_plain_step_bit_for_bit(on_goal, batch, layout_name, n):
    layout = preset(layout_name)
    rng = np.random.default_rng(batch * 7 + n)
    config = EnvConfig.make(n_robots=n, groups=2, layout=layout_name, on_goal=on_goal,
                            horizon=60)
    fast, plain = WarehouseCore(config, layout), PlainCore(config, layout)
    seen = set()
    for episode in range(3):
        starts, goals = sample_scenarios(layout, n, batch, rng)
        for b in range(batch):  # robot 0 starts on its goal (done at t = 0) where valid
            if starts[b, 0] not in goals[b, 1:]:
                goals[b, 0] = starts[b, 0]
        fast.reset(starts, goals)
        plain.reset(starts, goals)
        for _ in range(70):
            if fast.ended.all():
                break
            # Mostly greedy (robots reach goals, episodes end early), some random moves.
            prog = fast.dist[..., None] - fast.distances_to_goal(layout.next_cell[fast.pos])
            acts = np.where(rng.random((batch, n)) < 0.6, prog.argmax(axis=-1),
                            rng.integers(0, N_ACTIONS, (batch, n)))
            if episode == 2:
                acts = acts.astype(np.int8)  # another integer dtype
            got = fast.step(acts.copy())
            want = plain.step(acts.copy())
            for f in fields(StepResult):
                g, w = getattr(got, f.name), getattr(want, f.name)
                assert g.dtype == w.dtype and g.shape == w.shape, f.name
                assert np.array_equal(g, w) and g.tobytes() == w.tobytes(), f.name
            for name in STATE:
                g, w = getattr(fast, name), getattr(plain, name)
                assert np.array_equal(g, w) and np.asarray(g).dtype == np.asarray(w).dtype, name
            seen.update(k for k, v in [("collision", got.collision.any()),
                                       ("reached", got.reached.any()),
                                       ("partly_ended", fast.ended.any() and not fast.ended.all()),
                                       ("terminated", got.terminated.any()),
                                       ("truncated", got.truncated.any())] if v)
    assert {"collision", "reached"} <= seen and seen & {"terminated", "truncated"}, seen
    if layout_name == "tiny" and on_goal == "remove":
        assert "terminated" in seen and (batch == 1 or "partly_ended" in seen), seen


def test_step_checked__equals_step():
    layout = preset("wh20")
    config = EnvConfig.make(n_robots=20, groups=4)
    rng = np.random.default_rng(0)
    a = WarehouseCore(config, layout)
    a.reset(*sample_scenarios(layout, 20, 2, rng))
    b = copy.deepcopy(a)
    for _ in range(30):
        acts = rng.integers(0, N_ACTIONS, (2, 20))
        ra, rb = a.step(acts), b.step_checked(acts)
        for f in fields(StepResult):
            assert np.array_equal(getattr(ra, f.name), getattr(rb, f.name)), f.name
