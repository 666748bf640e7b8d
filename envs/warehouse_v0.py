"""PettingZoo ``ParallelEnv`` over the batched core with B = 1 (SPEC 2, "PettingZoo").

A thin adapter: dynamics, collisions and rewards are ``WarehouseCore``'s; observations are
``envs.observations.robot_features`` (local patch showing only same-group robots); the
lossy channel is ``GroupChannel``. All randomness (scenario sampling, message loss) comes
from the env's own ``np.random.Generator``: ``reset(seed=s)`` re-seeds it with
``np.random.default_rng(s)``, draws the scenario exactly as
``sample_scenarios(layout, N, 1, rng)`` would, then spawns the channel's generator.

Agents ``robot_0 .. robot_{N-1}``; ``Discrete(5)`` actions (Up, Down, Left, Right, Wait);
observations ``{"observation": float32 features, "action_mask": int8 (5,)}``. Every
agent alive at the start of a step receives the team reward R_t of eq:reward. With
``on_goal="remove"`` a robot that completes its task is terminated and leaves
``agents``; with ``"stay"`` it remains (Wait only) until the episode ends. At the
horizon every remaining agent is truncated.
"""
from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from envs.actions import N_ACTIONS, WAIT
from envs.channel import GroupChannel, group_assignment
from envs.config import EnvConfig
from envs.core import StepResult, WarehouseCore
from envs.errors import BenchError
from envs.layouts import Layout, load_layout
from envs.observations import PatchExtractor, feature_size, robot_features
from envs.render import render_ansi, render_rgb, write_gif
from envs.scenarios import sample_scenarios, validate_scenario

RENDER_MODES = ("rgb_array", "ansi")


def parallel_env(**kwargs: Any) -> WarehouseParallelEnv:
    """Build the env; keywords are ``EnvConfig`` fields plus the adapter's own options."""
    return WarehouseParallelEnv(**kwargs)


class WarehouseParallelEnv(ParallelEnv):
    """The warehouse as a PettingZoo parallel env (one episode, N robots)."""

    metadata = {"name": "warehouse_v0", "render_modes": list(RENDER_MODES),
                "is_parallelizable": True, "render_fps": 8}

    def __init__(
        self,
        render_mode: str | None = None,
        obs_radius: int = 2,
        record: bool = False,
        cell_px: int | None = None,
        layout: str | Layout = "wh20",
        **config: Any,
    ) -> None:
        """``render_mode``: "rgb_array", "ansi" or None. ``obs_radius``: k of the
        (2k+1)^2 local patch. ``record``: keep an RGB frame per step for
        ``write_episode_gif``. ``cell_px``: pixels per cell in frames (default: auto).
        ``layout``: preset name, ``.map``/``.txt`` path or a ``Layout``. Other keywords
        are ``EnvConfig`` fields (``n_robots``, ``groups``, ``loss_p``, ``horizon``, ...).
        """
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise BenchError(
                f"render_mode {render_mode!r} not supported; use one of {', '.join(RENDER_MODES)} or None"
            )
        if not isinstance(obs_radius, int) or obs_radius < 0:
            raise BenchError(f"obs_radius must be an integer >= 0, got {obs_radius!r}")
        lay = layout if isinstance(layout, Layout) else None
        self.config = EnvConfig.make(layout=lay.name if lay else layout, **config)
        self.layout = lay if lay is not None else load_layout(self.config.layout)
        self.render_mode = render_mode
        self.obs_radius = obs_radius
        self.record = record
        self.cell_px = cell_px
        n, z = self.config.n_robots, self.config.groups
        self.core = WarehouseCore(self.config, self.layout)
        self.patch = PatchExtractor(self.core, obs_radius)
        self.groups = group_assignment(n, z)  # (N,)
        self.possible_agents = [f"robot_{i}" for i in range(n)]
        self.agent_ids = {a: i for i, a in enumerate(self.possible_agents)}
        self.agents: list[str] = []

        h, w = self.layout.shape
        size = feature_size(obs_radius)
        low = np.zeros(size, np.float32)
        high = np.ones(size, np.float32)
        low[2:4] = -1.0  # goal offset / shape
        high[4] = max(1.0, h * w / (h + w))  # min(D, H W) / (H + W)
        low[6 : 6 + N_ACTIONS] = -1.0  # action progress
        obs_space = spaces.Dict({
            "observation": spaces.Box(low, high, dtype=np.float32),
            "action_mask": spaces.Box(0, 1, (N_ACTIONS,), dtype=np.int8),
        })
        # One object per agent, created once: observation_space(a) is observation_space(a).
        self._obs_spaces = {a: obs_space if i == 0 else _clone(obs_space)
                            for i, a in enumerate(self.possible_agents)}
        self._act_spaces = {a: spaces.Discrete(N_ACTIONS) for a in self.possible_agents}
        self.state_space = spaces.Box(0.0, 1.0, (5 * n + 1,), dtype=np.float32)

        self._rng: np.random.Generator | None = None
        self.channel: GroupChannel | None = None
        self.links = np.zeros((z, z), dtype=bool)  # A_t[z', z] of the current step
        self._last: StepResult | None = None
        self.frames: list[np.ndarray] = []

    # ----------------------------------------------------------------- spaces
    def observation_space(self, agent: str) -> spaces.Space:
        return self._obs_spaces[agent]

    def action_space(self, agent: str) -> spaces.Space:
        return self._act_spaces[agent]

    # ------------------------------------------------------------------ reset
    def reset(self, seed: int | None = None, options: dict | None = None
              ) -> tuple[dict[str, dict], dict[str, dict]]:
        """Start an episode. ``options={"starts": [(r, c), ...], "goals": [...]}`` gives
        an explicit scenario (validated); otherwise it is sampled. Other keys are ignored.
        """
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng(seed)
        options = options or {}
        n = self.config.n_robots
        if "starts" in options or "goals" in options:
            if "starts" not in options or "goals" not in options:
                raise BenchError("reset options: give both 'starts' and 'goals' (lists of (row, col))")
            s, g = validate_scenario(self.layout, n, options["starts"], options["goals"])
            starts, goals = s[None], g[None]
        else:
            starts, goals = sample_scenarios(self.layout, n, 1, self._rng)
        self.core.reset(starts, goals)
        self.channel = GroupChannel(self.config, 1, self._rng.spawn(1)[0])
        self.links = self.channel.step()[0]  # A_0
        self._last = None
        # A robot placed on its own goal has completed at t = 0 ("remove": off the floor).
        live = ~self.core.done[0] if self.core.remove else np.ones(n, bool)
        self.agents = [a for a, keep in zip(self.possible_agents, live, strict=True) if keep]
        self.frames = []
        if self.record:
            self.frames.append(self._frame())
        obs = self._observations(self.agents)
        zero = np.zeros(n)
        infos = self._infos(self.agents, zero, zero, zero, zero, np.zeros(n, bool),
                            np.zeros(n, bool))
        return obs, infos

    # ------------------------------------------------------------------- step
    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        """Advance one step. Every live agent needs an action; others are ignored."""
        if not self.agents:
            return {}, {}, {}, {}, {}
        unknown = set(actions) - set(self.agent_ids)
        if unknown:
            raise BenchError(f"step: unknown agents {sorted(unknown)}")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise BenchError(f"step: no action for live agents {missing}")
        n = self.config.n_robots
        u = np.full((1, n), WAIT, dtype=np.int64)
        for a in self.agents:
            u[0, self.agent_ids[a]] = int(actions[a])
        res = self.core.step(u)
        self._last = res
        self.links = self.channel.step()[0]  # A_{t+1}: messages carrying X_{t+1}

        live = self.agents
        team = float(res.reward[0])
        rewards = dict.fromkeys(live, team)
        ended = bool(res.terminated[0] or res.truncated[0])
        reached = res.reached[0]
        if self.core.remove:
            term = {a: bool(reached[self.agent_ids[a]] or res.terminated[0]) for a in live}
        else:
            term = dict.fromkeys(live, bool(res.terminated[0]))
        trunc = {a: bool(res.truncated[0]) and not term[a] for a in live}
        obs = self._observations(live)
        infos = self._infos(live, res.progress[0], res.goal_bonus[0], res.collision_penalty[0],
                            res.time_penalty[0], res.collision[0], res.invalid[0])
        self.agents = [] if ended else [a for a in live if not term[a]]
        if self.record:
            self.frames.append(self._frame())
        return obs, rewards, term, trunc, infos

    # --------------------------------------------------------- per-agent views
    def action_masks(self) -> np.ndarray:
        """(N, 5) int8: 1 for actions that move (or Wait); only Wait for robots whose task
        is complete (they cannot move in either ``on_goal`` mode)."""
        mask = self.layout.move_valid[self.core.pos[0]].astype(np.int8)
        mask[self.core.done[0], :WAIT] = 0
        return mask

    def _observations(self, agents: list[str]) -> dict[str, dict]:
        feats = robot_features(self.core, self.patch, self.groups)[0]  # (N, F)
        mask = self.action_masks()
        return {a: {"observation": feats[i], "action_mask": mask[i]}
                for a in agents for i in (self.agent_ids[a],)}

    def _infos(self, agents: list[str], progress: np.ndarray, goal_bonus: np.ndarray,
               collision_penalty: np.ndarray, time_penalty: np.ndarray,
               collision: np.ndarray, invalid: np.ndarray) -> dict[str, dict]:
        cells = self.layout.cells
        pos = cells[self.core.pos[0]].tolist()
        goal = cells[self.core.goal[0]].tolist()
        at_goal = (self.core.pos[0] == self.core.goal[0]).tolist()
        mask = self.action_masks()
        links_in = self.links.T  # [z, z']: does z receive from z' this step
        c_hier, c_dec = self.channel.payload_hier, self.channel.payload_dec
        out = {}
        for a in agents:
            i = self.agent_ids[a]
            z = int(self.groups[i])
            out[a] = {
                "position": tuple(pos[i]), "goal": tuple(goal[i]), "group": z,
                "collision": bool(collision[i]), "at_goal": at_goal[i],
                "invalid": bool(invalid[i]), "action_mask": mask[i],
                "progress": float(progress[i]), "goal_bonus": float(goal_bonus[i]),
                "collision_penalty": float(collision_penalty[i]),
                "time_penalty": float(time_penalty[i]),
                "link_available": links_in[z], "payload_hier": c_hier, "payload_dec": c_dec,
                "t": self.core.t,
            }
        return out

    def state(self) -> np.ndarray:
        """(5 N + 1,) float32 global state: positions and goals (row/H, col/W), completed
        flags, t/T."""
        h, w = self.layout.shape
        scale = np.array([h, w], np.float32)
        cells = self.layout.cells
        parts = [
            (cells[self.core.pos[0]] / scale).reshape(-1),
            (cells[self.core.goal[0]] / scale).reshape(-1),
            self.core.done[0].astype(np.float32),
            np.array([min(1.0, self.core.t / self.config.horizon)]),
        ]
        return np.concatenate(parts).astype(np.float32)

    # -------------------------------------------------------------- rendering
    def _render_args(self) -> tuple[tuple, dict]:
        cells = self.layout.cells
        core = self.core
        args = (self.layout, cells[core.pos[0]], cells[core.goal[0]], self.groups)
        kw = dict(done=core.done[0], on_floor=core.occupying[0],
                  collision=None if self._last is None else self._last.collision[0])
        return args, kw

    def _frame(self) -> np.ndarray:
        args, kw = self._render_args()
        links = self.links if self.config.groups > 1 else None
        return render_rgb(*args, **kw, links=links, adjacency=self.channel.adjacency,
                          cell_px=self.cell_px)

    def render(self) -> np.ndarray | str | None:
        if self.render_mode is None:
            gymnasium.logger.warn("render() called without a render_mode; returning None")
            return None
        if self.channel is None:
            raise BenchError("render: call reset() first")
        if self.render_mode == "rgb_array":
            return self._frame()
        args, kw = self._render_args()
        header = f"t={self.core.t}/{self.config.horizon} agents={len(self.agents)}"
        return render_ansi(*args, **kw, header=header)

    def write_episode_gif(self, path: str, fps: float | None = None) -> str:
        """Write the frames recorded since the last reset (needs ``record=True``)."""
        if not self.frames:
            raise BenchError("write_episode_gif: no frames recorded; create the env with record=True")
        fps = self.metadata["render_fps"] if fps is None else fps
        return str(write_gif(self.frames, path, fps=fps))

    def close(self) -> None:
        self.frames = []


def _clone(space: spaces.Dict) -> spaces.Dict:
    """An equal but distinct Dict space (each agent seeds its own sampler)."""
    return spaces.Dict({k: spaces.Box(v.low, v.high, v.shape, v.dtype) for k, v in space.items()})
