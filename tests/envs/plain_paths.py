"""The plain formulas that faster code in ``envs`` replaced, kept as test references.

``PlainCore``: ``WarehouseCore.step`` and its conflict resolution as first written.
``PlainParallelEnv``: the PettingZoo adapter's step, masks and observations as first
written, over ``PlainCore`` and ``np.concatenate([state_features, patch(groups)])``.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from envs.actions import N_ACTIONS, WAIT
from envs.core import StepResult, WarehouseCore
from envs.errors import BenchError
from envs.observations import PatchExtractor, state_features
from envs.pz_inputs import action_vector
from envs.warehouse_v0 import WarehouseParallelEnv


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
        idx = self._idx
        claim = np.zeros(self._claim.shape, dtype=np.int64)  # fresh work grids
        occ_grid = np.full(claim.shape, -1, dtype=np.int64)
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


class PlainParallelEnv(WarehouseParallelEnv):
    """``warehouse_v0`` with the step of commit 40869b6 over the plain core and features."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.core = PlainCore(self.config, self.layout)
        self.patch = PatchExtractor(self.core, self.obs_radius)

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        if self.channel is None:
            raise BenchError("step: call reset() before step()")
        if self.core.ended[0]:
            raise BenchError(
                f"step: the episode ended at t={self.core.t} (no agents left); call reset()")
        u = action_vector(actions, self.possible_agents, self.agent_ids, self._live,
                          self._actions)
        res = self.core.step(u[None])
        self._last = res
        self.links = self.channel.step()[0]
        self._hold()

        names = self.agents
        everyone = len(names) == self.config.n_robots
        live = None if everyone else np.flatnonzero(self._live)
        terminated, truncated = bool(res.terminated[0]), bool(res.truncated[0])
        if terminated or not self.core.remove:
            term = np.full(len(names), terminated)
        else:
            term = self.core.done[0] if everyone else self.core.done[0, live]
        rewards = dict.fromkeys(names, float(res.reward[0]))
        any_term = bool(term.any())
        terminations = (dict(zip(names, term.tolist(), strict=True)) if any_term
                        else dict.fromkeys(names, False))
        truncations = (dict(zip(names, (~term).tolist(), strict=True)) if truncated
                       else dict.fromkeys(names, False))
        obs = self._observations(live)
        infos = self._infos(names, res.progress[0], res.goal_bonus[0], res.collision_penalty[0],
                            res.time_penalty[0], res.collision[0], res.invalid[0])
        if terminated or truncated:
            self._live[:] = False
            self.agents = []
        elif any_term:
            self._live[np.flatnonzero(self._live)[term]] = False
            self.agents = [a for a, done in zip(names, term.tolist(), strict=True) if not done]
        if self.record:
            self.frames.append(self._frame())
        return obs, rewards, terminations, truncations, infos

    def action_masks(self) -> np.ndarray:
        mask = self.layout.move_valid[self.core.pos[0]].astype(np.int8)
        mask[self.core.done[0], :WAIT] = 0
        return mask

    def _observations(self, idx: np.ndarray | None, names: list[str] | None = None
                      ) -> dict[str, Any]:
        core = self.core
        b, n = core.pos.shape
        feats = np.concatenate([state_features(core), self.patch(self.groups).reshape(b, n, -1)],
                               axis=-1)[0]
        mask = self.action_masks()
        if idx is None:
            names = self.possible_agents
        else:
            names = [self.possible_agents[i] for i in idx.tolist()]
            feats, mask = feats[idx], mask[idx]
        if self.flat_obs:
            return dict(zip(names, np.concatenate([feats, mask.astype(np.float32)], axis=1),
                            strict=True))
        return {a: {"observation": f, "action_mask": m}
                for a, f, m in zip(names, feats, mask, strict=True)}
