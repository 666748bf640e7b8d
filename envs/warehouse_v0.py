"""PettingZoo ``ParallelEnv`` over the batched core with B = 1 (SPEC 2, "PettingZoo").

A thin adapter: dynamics, collisions and rewards are ``WarehouseCore``'s; observations are
``envs.observations.robot_features`` (local patch showing only same-group robots); the
lossy channel is the environment's inter-group ``Channel`` (``envs.channel.open_channel``).
All randomness (scenario sampling, message loss) comes from the env's own
``np.random.Generator``: ``reset(seed=s)`` re-seeds it with ``np.random.default_rng(s)``, draws the scenario exactly as
``sample_scenarios(layout, N, 1, rng)`` would, then spawns the channel's generator.

Agents ``robot_0 .. robot_{N-1}``; ``Discrete(5)`` actions (Up, Down, Left, Right, Wait);
observations ``{"observation": float32 features, "action_mask": int8 (5,)}`` (the mask
lives there only, where TorchRL and PettingZoo's classic envs look for it), or with
``flat_obs=True`` one float32 Box: the features followed by the 5 mask entries (for
SuperSuit/Stable-Baselines3). Every agent alive at the start of a step receives the team
reward R_t of eq:reward. Every robot is in ``agents`` after ``reset`` (a fixed agent set
for wrappers), including one placed on its own goal: it has completed at t = 0, so it
may only Wait and, with ``on_goal="remove"``, is terminated at the first step. With
``on_goal="remove"`` a robot that completes its task is terminated and leaves ``agents``;
with ``"stay"`` it remains (Wait only) until the episode ends, so the agent set is fixed
for the whole episode. At the horizon every remaining agent is truncated.

Observations and infos of all agents are built at once from the batched core: each
agent's arrays are row views of one (N, ...) array per step, and ``infos`` is a dict whose
per-agent dicts are built on first read from copies of the step's (N,) arrays
(``envs.step_infos``). Bad input raises ``envs.errors.BenchError`` (a
``ValueError``) naming the agent or option and the value (``envs.pz_inputs``).
"""
from __future__ import annotations

import sys
from functools import partial
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from envs.actions import N_ACTIONS, WAIT
from envs.channel import Channel, group_assignment, open_channel
from envs.config import EnvConfig
from envs.core import StepResult, WarehouseCore
from envs.errors import BenchError
from envs.layouts import Layout, load_layout
from envs.observations import PatchExtractor, feature_size, robot_features
from envs.pz_inputs import action_vector, scenario_options
from envs.render import render_ansi, render_rgb, show_in_terminal, write_gif
from envs.scenarios import sample_scenarios, validate_scenario
from envs.step_infos import StepInfos
from envs.tasks import TaskStream

RENDER_MODES = ("human", "rgb_array", "ansi")


def parallel_env(**kwargs: Any) -> WarehouseParallelEnv:
    """Build the env; keywords are ``EnvConfig`` fields plus the adapter's own options."""
    return WarehouseParallelEnv(**kwargs)


class WarehouseParallelEnv(ParallelEnv):
    """The warehouse as a PettingZoo parallel env (one episode, N robots)."""

    metadata: dict[str, Any] = {"name": "warehouse_v0", "render_modes": list(RENDER_MODES),
                "is_parallelizable": True, "render_fps": 8}

    def __init__(
        self,
        render_mode: str | None = None,
        obs_radius: int = 2,
        record: bool = False,
        cell_px: int | None = None,
        layout: str | Layout = "wh20",
        flat_obs: bool = False,
        **config: Any,
    ) -> None:
        """``render_mode``: "human" (text frames printed to the terminal), "rgb_array",
        "ansi" or None. ``obs_radius``: k of the (2k+1)^2 local patch. ``record``: keep an
        RGB frame per step for ``write_episode_gif``. ``cell_px``: pixels per cell in
        frames (default: auto). ``layout``: preset name, ``.map``/``.txt`` path or a
        ``Layout``. ``flat_obs``: observations as one float32 Box [features, action
        mask] instead of a Dict. Other keywords are ``EnvConfig`` fields (``n_robots``,
        ``groups`` (default min(4, n_robots)), ``loss_p``, ``horizon``, ``on_goal``, ...).
        """
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise BenchError(
                f"render_mode {render_mode!r} not supported; use one of {', '.join(RENDER_MODES)} or None"
            )
        if type(obs_radius) is not int or obs_radius < 0:
            raise BenchError(f"obs_radius must be an integer >= 0, got {obs_radius!r}")
        if not isinstance(flat_obs, bool):
            raise BenchError(f"flat_obs must be True or False, got {flat_obs!r}")
        lay = layout if isinstance(layout, Layout) else None
        self.config = EnvConfig.make(layout=lay.name if lay else layout, **config)
        self.layout = lay if lay is not None else load_layout(self.config.layout)
        self.render_mode = render_mode
        self.obs_radius = obs_radius
        self.flat_obs = flat_obs
        self.record = record
        self.cell_px = cell_px
        n, z = self.config.n_robots, self.config.groups
        self.core = WarehouseCore(self.config, self.layout)
        self.patch = PatchExtractor(self.core, obs_radius)
        self.groups = group_assignment(n, z)  # (N,)
        self.possible_agents = [f"robot_{i}" for i in range(n)]
        self.agent_ids = {a: i for i, a in enumerate(self.possible_agents)}
        self.agents: list[str] = []
        self._live = np.zeros(n, dtype=bool)  # (N,) robots in ``agents``
        self._actions = np.full(n, WAIT, dtype=np.int64)  # (N,) scratch for step()
        self._tmpl: tuple | None = None  # see _templates()
        # (F + 1, 5) int8 action mask by cell; the last row (only Wait) for finished robots.
        self._mask_table = np.concatenate(
            [self.layout.move_valid, np.arange(N_ACTIONS)[None] == WAIT]).astype(np.int8)

        h, w = self.layout.shape
        size = feature_size(obs_radius)
        low = np.zeros(size, np.float32)
        high = np.ones(size, np.float32)
        low[2:4] = -1.0  # goal offset / shape
        high[4] = max(1.0, h * w / (h + w))  # min(D, H W) / (H + W)
        low[6 : 6 + N_ACTIONS] = -1.0  # action progress
        if flat_obs:
            low = np.concatenate([low, np.zeros(N_ACTIONS, np.float32)])
            high = np.concatenate([high, np.ones(N_ACTIONS, np.float32)])
            obs_space: spaces.Space = spaces.Box(low, high, dtype=np.float32)
        else:
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
        self.channel: Channel | None = None
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
              ) -> tuple[dict[str, Any], dict[str, dict]]:
        """Start an episode. ``options={"starts": [(r, c), ...], "goals": [...]}`` gives
        an explicit scenario (validated; integer cells only); otherwise it is sampled
        (never with a robot on its own goal). A misspelt key (``"start"``) is an error;
        other keys are ignored with a warning.
        """
        scenario = scenario_options(options)
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng(seed)
        n = self.config.n_robots
        if scenario:
            s, g = validate_scenario(self.layout, n, scenario["starts"], scenario["goals"])
            starts, goals = s[None], g[None]
        else:
            starts, goals = sample_scenarios(self.layout, n, 1, self._rng)
        self.channel = open_channel(self.config, 1, self._rng.spawn(1)[0])
        tasks = None  # lifelong: the next goals, from a child of the env's generator
        if self.core.lifelong:
            tasks = TaskStream.seeded(self.layout, n, 1, self._rng.spawn(1)[0])
        self.core.reset(starts, goals, tasks)
        self.links = self.channel.step()[0]  # A_0
        self._held = np.full(self.links.shape, -1, dtype=np.int64)  # send step of what z holds from z'
        self._hold()
        self._last = None
        # Every robot starts in ``agents``, even one placed on its goal (done at t = 0).
        self._live[:] = True
        self.agents = list(self.possible_agents)
        self.frames = []
        if self.record:
            self.frames.append(self._frame())
        zero = np.zeros(n)
        no = np.zeros(n, dtype=bool)
        return (self._observations(None),
                self._infos(self._templates()[2], zero, zero, zero, zero, no, no))

    # ------------------------------------------------------------------- step
    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        """Advance one step. Every live agent needs an integer action in 0..4; agents
        that already left may be absent or given None or a valid action (ignored)."""
        if self.channel is None:
            raise BenchError("step: call reset() before step()")
        if self.core.ended[0]:
            raise BenchError(
                f"step: the episode ended at t={self.core.t} (no agents left); call reset()")
        u = action_vector(actions, self.possible_agents, self.agent_ids, self._live,
                          self._actions)
        res = self.core.step_checked(u[None])  # action_vector checked every action
        self._last = res
        self.links = self.channel.step()[0]  # A_{t+1}: messages carrying X_{t+1}
        self._hold()

        names = self.agents  # alive at the start of this step, in index order
        false, true, pending, live = self._templates()
        terminated, truncated = bool(res.terminated[0]), bool(res.truncated[0])
        # "remove": a robot is terminated the step it completes (or at the first step if
        # it started on its goal); "stay": only when the whole team has completed.
        term = None  # per-agent flags, when they differ
        if terminated:
            terminations = true.copy()
        elif self.core.remove:
            done = self.core.done[0]
            term = done if live is None else done[live]
            if np.count_nonzero(term):
                terminations = dict(zip(names, term.tolist(), strict=True))
            else:
                term, terminations = None, false.copy()
        else:
            terminations = false.copy()
        if not truncated:
            truncations = false.copy()
        elif term is None:
            truncations = true.copy()
        else:
            truncations = dict(zip(names, (~term).tolist(), strict=True))
        rewards = dict.fromkeys(false, float(res.reward[0]))
        obs = self._observations(live, names)
        infos = self._infos(pending, res.progress[0], res.goal_bonus[0],
                            res.collision_penalty[0], res.time_penalty[0], res.collision[0],
                            res.invalid[0])
        if terminated or truncated:
            self._live[:] = False
            self.agents = []
        elif term is not None:
            self._live[np.flatnonzero(self._live)[term]] = False
            self.agents = [a for a, done in zip(names, term.tolist(), strict=True) if not done]
        if self.record:
            self.frames.append(self._frame())
        return obs, rewards, terminations, truncations, infos

    def _hold(self) -> None:
        """Update the send step of the freshest message each group holds from each other
        (the channel's own record under a delay; the last delivery otherwise)."""
        channel = self._live_channel()
        if channel.sent_at is not None:
            self._held = channel.sent_at[0].copy()
        else:
            self._held[self.links] = self.core.t

    def message_ages(self) -> np.ndarray:
        """(Z, Z) int [z', z]: steps since the freshest message z holds from z' was sent
        (t + 1 when none has arrived yet; 0 on the diagonal: a group knows its own state)."""
        ages = self.core.t - self._held
        np.fill_diagonal(ages, 0)
        return ages

    def _templates(self) -> tuple[dict, dict, dict, np.ndarray | None]:
        """{agent: False}, {agent: True} and StepInfos' pending dict over ``agents``, and
        their robot indices (None: all N): built when ``agents`` changes (``reset`` and
        ``step`` replace the list, never edit it), copied by each step."""
        names = self.agents
        cached = self._tmpl
        if cached is None or cached[0] is not names:
            live = None if len(names) == self.config.n_robots else np.flatnonzero(self._live)
            cached = self._tmpl = (names, dict.fromkeys(names, False),
                                   dict.fromkeys(names, True), StepInfos.template(names), live)
        return cached[1:]

    # --------------------------------------------------------- per-agent views
    def action_masks(self) -> np.ndarray:
        """(N, 5) int8: 1 for actions that move (or Wait); only Wait for robots whose task
        is complete (they cannot move in either ``on_goal`` mode)."""
        done = self.core.done[0]
        cells = self.core.pos[0]
        if np.count_nonzero(done):
            cells = np.where(done, len(self._mask_table) - 1, cells)
        return self._mask_table[cells]  # a new array

    def _observations(self, idx: np.ndarray | None, names: list[str] | None = None
                      ) -> dict[str, Any]:
        """Observations of robots ``idx`` (None: all) named ``names`` (default: theirs):
        row views of one (N, F) feature array and one (N, 5) mask array of this step."""
        feats = robot_features(self.core, self.patch, self.groups)[0]  # (N, F)
        mask = self.action_masks()
        if idx is not None:
            feats, mask = feats[idx], mask[idx]
        if names is None:
            names = (self.possible_agents if idx is None
                     else [self.possible_agents[i] for i in idx.tolist()])
        if self.flat_obs:
            return dict(zip(names, np.concatenate([feats, mask.astype(np.float32)], axis=1),
                            strict=True))
        # list(): the row views in one C loop (faster than zip over the arrays themselves)
        return {a: {"observation": f, "action_mask": m}
                for a, f, m in zip(names, list(feats), list(mask), strict=True)}

    def _infos(self, names: list[str] | dict, progress: np.ndarray, goal_bonus: np.ndarray,
               collision_penalty: np.ndarray, time_penalty: np.ndarray,
               collision: np.ndarray, invalid: np.ndarray) -> StepInfos:
        """Infos of agents ``names`` (or their ``StepInfos.template``; keys
        ``INFO_KEYS``), built on first read from copies of this step's (N,) arrays
        (``envs.step_infos``)."""
        # Copies (a few hundred bytes): the infos must not change if the core or the
        # channel ever reuse their arrays in place.
        columns = partial(_info_columns, self.layout.cells, self.core.pos[0].copy(),
                          self.core.goal[0].copy(), self.groups, self.links.copy(), self.message_ages(),
                          progress.copy(),
                          goal_bonus.copy(), collision_penalty.copy(), time_penalty.copy(),
                          collision.copy(), invalid.copy())
        channel = self._live_channel()
        constants = {"payload_hier": channel.payload_hier, "payload_dec": channel.payload_dec,
                     "t": self.core.t}
        return StepInfos(names, self.agent_ids, columns, constants)

    def state(self) -> np.ndarray:
        """(5 N + 1,) float32 global state: positions and goals (row/H, col/W), completed
        flags, t/T."""
        if self.channel is None:
            raise BenchError("state: call reset() before state()")
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

    def _live_channel(self) -> Channel:
        """The channel of the current episode (set by ``reset``)."""
        if self.channel is None:
            raise BenchError("call reset() first")
        return self.channel

    def _frame(self) -> np.ndarray:
        args, kw = self._render_args()
        links = self.links if self.config.groups > 1 else None
        return render_rgb(*args, **kw, links=links, adjacency=self._live_channel().adjacency,
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
        text = render_ansi(*args, **kw, header=header)
        if self.render_mode == "human":
            show_in_terminal(text, sys.stdout)
            return None
        return text

    def write_episode_gif(self, path: str, fps: float | None = None) -> str:
        """Write the frames recorded since the last reset (needs ``record=True``)."""
        if not self.frames:
            raise BenchError("write_episode_gif: no frames recorded; create the env with record=True")
        fps = self.metadata["render_fps"] if fps is None else fps
        return str(write_gif(self.frames, path, fps=fps))

    def close(self) -> None:
        self.frames = []


def _info_columns(cells: np.ndarray, pos: np.ndarray, goal: np.ndarray, groups: np.ndarray,
                  links: np.ndarray, ages: np.ndarray, progress: np.ndarray, goal_bonus: np.ndarray,
                  collision_penalty: np.ndarray, time_penalty: np.ndarray,
                  collision: np.ndarray, invalid: np.ndarray) -> dict[str, np.ndarray]:
    """The (N, ...) columns of ``StepInfos`` from cell indices pos/goal (N,), the cell
    table (F, 2) and A_t (Z, Z)."""
    return {
        "position": cells[pos], "goal": cells[goal], "group": groups,
        "collision": collision, "at_goal": pos == goal, "invalid": invalid,
        "progress": progress, "goal_bonus": goal_bonus,
        "collision_penalty": collision_penalty, "time_penalty": time_penalty,
        "link_available": links.T[groups],  # (N, Z): does z_i hear from z'
        "message_age": ages.T[groups],  # (N, Z): age of what z_i holds from z'
    }


def _clone(space: spaces.Space) -> spaces.Space:
    """An equal but distinct space (each agent seeds its own sampler)."""
    if isinstance(space, spaces.Box):
        return spaces.Box(space.low, space.high, space.shape, space.dtype)
    assert isinstance(space, spaces.Dict), space  # the observation spaces: Box leaves in Dicts
    return spaces.Dict({k: _clone(v) for k, v in space.items()})
