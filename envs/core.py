"""The batched warehouse core: B independent episodes of N robots stepped at once in numpy.

State arrays are shaped (B, N); positions are free-cell indices of the layout. One call to
``step`` advances every episode (no Python loop over robots or episodes). Semantics
(SPEC 2, eq:system_dynamics, eq:reward):

* a move into a shelf or off the grid leaves the robot in place (an *invalid move*);
* robot i is *in collision* if its intended next cell equals another robot's intended next
  cell (vertex conflict; includes entering the cell of a robot that stays) or i and j swap
  cells (edge conflict). Colliding movers stay where they are; this repeats until no
  conflict remains (cascades). Every robot involved in a conflict in any round has the
  collision indicator of eq:reward set (except a completed robot, whose terms are all 0,
  docs/decisions/0004). Following a robot that leaves is allowed, and so is a rotation
  of robots each entering the cell the next one leaves around a cycle (a 4-connected grid
  has only even cycles, so it takes four or more robots, e.g. a 2x2 block; two robots
  trading cells is an edge conflict). In POGEMA's terms this is its ``soft`` collision
  system without the rule that the lowest-index robot wins a contested cell;
* a robot completes its task the first step it stands on its goal. ``on_goal="remove"``:
  it then leaves the floor; ``"stay"``: it remains as an obstacle and only Waits;
* an episode terminates when every robot has completed, and is truncated at t = T
  (kept apart). Finished episodes are frozen: stepping them changes nothing, rewards 0.
* ``task="lifelong"`` (beyond the paper): a robot never completes; each arrival earns
  the goal bonus and the robot's next goal comes from the episode's ``TaskStream``
  (envs/tasks.py) at once, so every robot works, and pays the time penalty, until the
  horizon truncates the episode (``on_goal`` does not apply: nobody leaves the floor).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envs.actions import N_ACTIONS, WAIT
from envs.config import EnvConfig
from envs.distances import distance_cache
from envs.errors import BenchError
from envs.layouts import Layout, load_layout
from envs.tasks import TaskStream


@dataclass
class StepResult:
    """What one batched step returns. Shapes in comments."""

    reward: np.ndarray  # (B,) float64 team reward R_t of eq:reward
    progress: np.ndarray  # (B, N) q_p (D(p_t, g) - D(p_{t+1}, g))
    goal_bonus: np.ndarray  # (B, N) q_g 1^g
    collision_penalty: np.ndarray  # (B, N) -q_c 1^c
    time_penalty: np.ndarray  # (B, N) -q_tau 1^u
    collision: np.ndarray  # (B, N) bool, involved in a conflict this step
    invalid: np.ndarray  # (B, N) bool, moved into a shelf or off the grid
    reached: np.ndarray  # (B, N) bool, reached the goal for the first time this step
    active: np.ndarray  # (B, N) bool, robot-steps that count (episode running, task unfinished)
    terminated: np.ndarray  # (B,) bool, all robots completed at this step
    truncated: np.ndarray  # (B,) bool, horizon reached at this step without termination


class WarehouseCore:
    """Batched dynamics, collisions and reward of the paper's warehouse (no randomness)."""

    def __init__(self, config: EnvConfig, layout: Layout | None = None) -> None:
        self.config = config
        self.layout = layout if layout is not None else load_layout(config.layout)
        self.n = config.n_robots
        self.horizon = config.horizon
        self.remove = config.on_goal == "remove" and config.task == "one-shot"
        w = config.reward
        self._q = (float(w.q_p), float(w.q_g), float(w.q_c), float(w.q_tau))
        self._next = np.ascontiguousarray(self.layout.next_cell.reshape(-1))  # (F*5,)
        self._invalid = ~self.layout.move_valid.reshape(-1)  # (F*5,) moves into a shelf
        self._dist = distance_cache(self.layout)
        self.batch = 0
        self.lifelong = config.task == "lifelong"
        self.tasks: TaskStream | None = None

    # ------------------------------------------------------------------ reset
    def reset(self, starts: np.ndarray, goals: np.ndarray, tasks: TaskStream | None = None) -> None:
        """Start B episodes from (B, N) start and goal cell indices; ``tasks`` gives the
        next goals of a lifelong episode (``task="lifelong"`` needs it, one-shot ignores it)."""
        if self.lifelong and tasks is None:
            raise BenchError("reset: a lifelong episode needs a task stream (envs.tasks.TaskStream)")
        starts = np.asarray(starts, dtype=np.int64)
        goals = np.asarray(goals, dtype=np.int64)
        if starts.ndim != 2 or starts.shape != goals.shape or starts.shape[1] != self.n:
            raise BenchError(
                f"reset: starts and goals must both be (B, {self.n}), got {starts.shape} and {goals.shape}"
            )
        b, n, f = starts.shape[0], self.n, self.layout.n_free
        for name, cells in (("starts", starts), ("goals", goals)):
            if cells.size and (cells.min() < 0 or cells.max() >= f):
                raise BenchError(f"reset: {name} must be free-cell indices in 0..{f - 1}, "
                                 f"got {int(cells.min())}..{int(cells.max())}")
        # Two robots on one cell would never leave the conflict resolution: refuse them.
        on_floor = ~(self.remove & (starts == goals))  # a robot starting on its goal is off the floor ("remove")
        keys = np.sort(np.where(on_floor, starts, -1 - np.arange(n)), axis=1)
        shared = keys[:, 1:] == keys[:, :-1]
        if shared.any():
            e, k = (int(v[0]) for v in np.nonzero(shared))
            raise BenchError(f"reset: episode {e} has two robots starting on free cell {int(keys[e, k])}")
        self.batch = b
        self.pos = starts.copy()  # (B, N) cell index p_t
        self.t = 0
        self.tasks = tasks if self.lifelong else None
        if self.tasks is not None:  # a robot placed on its goal gets its next one
            goals = goals.copy()
            on_goal = goals == starts
            if on_goal.any():
                goals[on_goal] = self.tasks.next_goals(on_goal, starts)
        self._set_goals(goals.copy(), per_robot=self.tasks is not None)
        self.done = self.pos == self.goal  # (B, N) task completed
        self.ended = np.zeros(b, dtype=bool)  # (B,) episode over
        self.prev_actions = np.full((b, n), WAIT, dtype=np.int64)  # U_{t-1}
        # Scratch grids for conflict detection, indexed by b*F + cell (+ B*N dummy slots).
        m = b * n
        self._base = (np.arange(b, dtype=np.int64) * f)[:, None]  # (B, 1)
        self._idx = np.arange(m, dtype=np.int64)
        self._dummy = b * f + self._idx
        self._claim = np.zeros(b * f + m, dtype=np.int64)
        self._dest = np.full(b * f + m, -1, dtype=np.int64)  # next key by current key

    def _set_goals(self, goals: np.ndarray, per_robot: bool = False) -> None:
        """Goals g (B, N) and what depends on them: their (row, col), the distance fields and
        D(p_t, g). One field per distinct goal, or with ``per_robot`` one per robot (lifelong
        goals change one robot at a time: ``_retarget`` then replaces only those fields)."""
        b, n, f = goals.shape[0], self.n, self.layout.n_free
        self.goal = goals
        self.goal_rc = self.layout.float_cells[self.goal]  # (B, N, 2) float32 (row, col) of g
        if per_robot:
            self._fields = np.ascontiguousarray(self._dist.fields(goals.reshape(-1)).reshape(-1))  # (B*N*F,)
            self._goal_base = np.arange(b * n, dtype=np.int64).reshape(b, n) * f
        else:
            uniq, inv = np.unique(self.goal, return_inverse=True)
            self._fields = np.ascontiguousarray(self._dist.fields(uniq).reshape(-1))  # (U*F,)
            self._goal_base = inv.reshape(b, n).astype(np.int64) * f  # (B, N)
        self.dist = self._fields[self._goal_base + self.pos]  # (B, N) D(p_t, g)

    def _retarget(self, reached: np.ndarray, goals: np.ndarray) -> None:
        """Lifelong: the robots where ``reached`` (B, N) get the next ``goals`` (C order);
        their fields are replaced in place (one field per robot, ``_set_goals``)."""
        f = self.layout.n_free
        self.goal = self.goal.copy()
        self.goal[reached] = goals
        self.goal_rc = self.layout.float_cells[self.goal]
        slots = self._goal_base[reached] // f
        self._fields.reshape(-1, f)[slots] = self._dist.fields(goals)
        self.dist = self._fields[self._goal_base + self.pos]

    @property
    def occupying(self) -> np.ndarray:
        """(B, N) bool: robots standing on the floor (blocking others)."""
        return ~self.done if self.remove else np.ones_like(self.done)

    def distances_to_goal(self, cells: np.ndarray) -> np.ndarray:
        """D(cells[b, i, ...], g_i) for (B, N, ...) cell indices."""
        base = self._goal_base.reshape(self._goal_base.shape + (1,) * (cells.ndim - 2))
        return self._fields[base + cells]

    # ------------------------------------------------------------------- step
    def step(self, actions: np.ndarray) -> StepResult:
        """Advance every running episode by one step with (B, N) actions in 0..4."""
        a = np.asarray(actions)
        if a.shape != self.pos.shape:
            raise BenchError(f"step: actions must be shaped {self.pos.shape}, got {a.shape}")
        if a.dtype.kind == "f" and not (np.isfinite(a).all() and (a == np.floor(a)).all()):
            flat = a.reshape(-1)  # cast, NaN or 2.5 would be a garbage index (D15)
            bad = flat[~(np.isfinite(flat) & (flat == np.floor(flat)))][0]
            raise BenchError(f"step: action {bad} is not an integer in 0..{N_ACTIONS - 1} "
                             "(Up, Down, Left, Right, Wait)")
        if a.size and (a.min() < 0 or a.max() >= N_ACTIONS):
            bad = int(a.reshape(-1)[(a.reshape(-1) < 0) | (a.reshape(-1) >= N_ACTIONS)][0])
            raise BenchError(f"step: action {bad} outside 0..{N_ACTIONS - 1} (Up, Down, Left, Right, Wait)")
        return self.step_checked(a)

    def step_checked(self, actions: np.ndarray) -> StepResult:
        """``step`` for actions already known to be a (B, N) integer array in 0..4 (the
        PettingZoo adapter checks each agent's action itself); the same results.

        Fewer array passes than the plain formulas for the common cases (every episode
        running, every robot on the floor, B = 1), bit for bit the same arrays
        (tests/envs/test_core_fast_path.py keeps the plain step as the reference).
        """
        # np.count_nonzero: a third of the cost of .any() on these small arrays
        all_running = not np.count_nonzero(self.ended)
        running = None if all_running else ~self.ended  # (B,)
        # Completed robots and finished episodes Wait.
        frozen = self.done if running is None else self.done | ~running[:, None]
        a = np.where(frozen, WAIT, actions).astype(np.int64, copy=False)  # a new array
        flat = self.pos * N_ACTIONS + a
        tgt = self._next[flat]  # a new array: _resolve edits it into the next keys
        invalid = self._invalid[flat]  # frozen robots Wait, always valid: no & active

        on_floor = not (self.remove and np.count_nonzero(self.done))  # all occupy their cells
        single = self.batch == 1  # b * F offsets are all 0
        key_now = (self.pos if single else self._base + self.pos).reshape(-1)
        key_next = (tgt if single else self._base + tgt).reshape(-1)
        if not on_floor:  # robots off the floor claim a private dummy slot
            occ = ~self.done.reshape(-1)
            key_now = np.where(occ, key_now, self._dummy)
            key_next = np.where(occ, key_next, self._dummy)
        collision = self._resolve(key_now, key_next)
        new_pos = key_next.reshape(self.pos.shape)
        if not single:
            new_pos = new_pos - self._base
        if not on_floor:
            new_pos = np.where(occ.reshape(self.pos.shape), new_pos, self.pos)
        active = ~frozen  # robot-steps that count for rates
        collision = collision.reshape(self.pos.shape)
        if not self.remove:
            # A completed robot that stays and is bumped into gets no terms
            # (docs/decisions/0004). Under "remove" it is off the floor, and in a finished
            # episode nobody moves: & active would change nothing.
            collision = collision & active

        q_p, q_g, q_c, q_tau = self._q
        new_dist = self._fields[self._goal_base + new_pos]
        reached = (new_pos == self.goal) & active if all_running else (
            ~self.done & (new_pos == self.goal))
        done = self.done | reached
        progress = np.multiply(q_p, self.dist - new_dist, dtype=np.float64)
        goal_bonus = q_g * reached
        collision_penalty = -q_c * collision
        # Active and unfinished; active = running & ~done_t, and done_{t+1} covers done_t.
        time_penalty = -q_tau * (~done if all_running else active & ~done)
        reward = (progress + goal_bonus + collision_penalty + time_penalty).sum(axis=1) / self.n

        self.pos, self.dist, self.done = new_pos, new_dist, done
        self.prev_actions = a
        self.t += 1
        if self.tasks is not None:  # lifelong: nobody completes, arrivals get a next goal
            self.done = done = self.done & False
            if np.count_nonzero(reached):
                self._retarget(reached, self.tasks.next_goals(reached, new_pos))
        terminated = done.all(axis=1)
        if not all_running:
            terminated &= running
        if self.t < self.horizon:
            truncated = np.zeros(self.batch, bool)
        else:
            truncated = ~terminated if all_running else running & ~terminated
        self.ended = self.ended | terminated | truncated
        return StepResult(
            reward=reward, progress=progress, goal_bonus=goal_bonus.astype(np.float64, copy=False),
            collision_penalty=collision_penalty,
            time_penalty=time_penalty.astype(np.float64, copy=False),
            collision=collision, invalid=invalid, reached=reached, active=active,
            terminated=terminated, truncated=truncated,
        )

    def _resolve(self, key_now: np.ndarray, key_next: np.ndarray) -> np.ndarray:
        """Revert conflicting moves in place of ``key_next`` until none remain.

        Returns (B*N,) bool: robots involved in a vertex or edge conflict in any round.
        Robots off the floor have private dummy keys (never claimed by another robot).

        Edge conflicts are looked for in the first round only: later rounds only revert
        robots to their current cell, so two robots still moving after round one kept
        the targets they had there, where any swap between them was already found.
        """
        idx, claim = self._idx, self._claim
        moving = key_next != key_now
        if not np.count_nonzero(moving):
            return np.zeros(idx.shape, dtype=bool)
        # Vertex conflicts: a key claimed by two or more robots. After the write each
        # claimed key holds one claimant (the last); every other claimant sees another
        # index there, and the one it sees is the remaining claimant of that key.
        claim[key_next] = idx
        conflict = claim[key_next] != idx
        conflict[claim[key_next[conflict]]] = True
        # Edge conflicts: i moves into j's cell while j moves into i's cell. dest[c] is
        # the next key of the robot whose key is c (-1 where none), so i swaps exactly
        # when it moves and dest[key_next[i]] == key_now[i]; j is found the same way.
        dest = self._dest
        dest[key_now] = key_next
        conflict |= moving & (dest[key_next] == key_now)
        dest[key_now] = -1
        collision = conflict
        while np.count_nonzero(conflict):
            # Reverting a robot that did not move rewrites its key with the same value.
            key_next[conflict] = key_now[conflict]
            claim[key_next] = idx
            conflict = claim[key_next] != idx
            conflict[claim[key_next[conflict]]] = True
            collision |= conflict
        return collision
