"""``WarehouseCore.step`` (fewer array passes for the common cases) against the plain
formulas it replaced, kept here verbatim: every returned array and the state after each
step are the same bit for bit, with the default (non-dyadic) reward weights, B = 1 and
B > 1, both ``on_goal`` modes, episodes ending at different times and robots leaving.

Runtime: about 1 s.
"""
from __future__ import annotations

import copy
from dataclasses import fields

import numpy as np
import pytest

from envs.actions import N_ACTIONS, WAIT
from envs.config import EnvConfig
from envs.core import StepResult, WarehouseCore
from envs.layouts import preset
from envs.scenarios import sample_scenarios


class PlainCore(WarehouseCore):
    """The core with the step and conflict resolution as first written."""

    def step(self, actions: np.ndarray) -> StepResult:
        valid = np.ascontiguousarray(self.layout.move_valid.reshape(-1))
        a = np.asarray(actions)
        running = ~self.ended  # (B,)
        frozen = self.done | ~running[:, None]
        a = np.where(frozen, WAIT, a).astype(np.int64)
        flat = self.pos * N_ACTIONS + a
        tgt = self._next[flat]
        invalid = ~valid[flat]

        occ = self.occupying.reshape(-1)
        key_now = (self._base + self.pos).reshape(-1)
        key_next = (self._base + tgt).reshape(-1)
        if not occ.all():
            key_now = np.where(occ, key_now, self._dummy)
            key_next = np.where(occ, key_next, self._dummy)
        collision = self._plain_resolve(key_now, key_next, occ)
        new_key = key_next
        new_pos = (new_key.reshape(self.pos.shape) - self._base)
        new_pos = np.where(occ.reshape(self.pos.shape), new_pos, self.pos)
        active = ~frozen
        collision = collision.reshape(self.pos.shape) & active

        q_p, q_g, q_c, q_tau = self._q
        new_dist = self._fields[self._goal_base + new_pos]
        reached = ~self.done & (new_pos == self.goal)
        done = self.done | reached
        progress = q_p * (self.dist - new_dist).astype(np.float64)
        goal_bonus = q_g * reached
        collision_penalty = -q_c * collision
        time_penalty = -q_tau * (active & ~done)
        reward = (progress + goal_bonus + collision_penalty + time_penalty).sum(axis=1) / self.n

        self.pos, self.dist, self.done = new_pos, new_dist, done
        self.prev_actions = a
        self.t += 1
        terminated = running & done.all(axis=1)
        truncated = running & ~terminated & (self.t >= self.horizon)
        self.ended = self.ended | terminated | truncated
        return StepResult(
            reward=reward, progress=progress, goal_bonus=goal_bonus.astype(np.float64),
            collision_penalty=collision_penalty, time_penalty=time_penalty.astype(np.float64),
            collision=collision, invalid=invalid & active, reached=reached, active=active,
            terminated=terminated, truncated=truncated,
        )

    def _plain_resolve(self, key_now, key_next, occ):
        idx, claim, occ_grid = self._idx, self._claim, self._occ
        flag = np.zeros(claim.shape, dtype=bool)
        collision = np.zeros(idx.shape, dtype=bool)
        moving = key_next != key_now
        if not moving.any():
            return collision
        occ_grid[key_now[occ]] = idx[occ]
        while True:
            claim[key_next] = idx
            dup_keys = key_next[claim[key_next] != idx]
            flag[dup_keys] = True
            conflict = flag[key_next]
            flag[dup_keys] = False
            ci = np.flatnonzero(moving)
            jj = occ_grid[key_next[ci]]
            swap = (jj >= 0) & (key_next[jj] == key_now[ci])
            conflict[ci[swap]] = True
            conflict[jj[swap]] = True
            if not conflict.any():
                break
            collision |= conflict
            revert = conflict & moving
            key_next[revert] = key_now[revert]
            moving &= ~revert
        occ_grid[key_now[occ]] = -1
        return collision


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
