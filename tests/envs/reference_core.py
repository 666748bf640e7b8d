"""A slow, per-robot reference of the warehouse step, written to be read, not to be fast.

It restates the semantics of ``envs/core.py`` (SPEC 2, eq:reward, docs/decisions/0002, 0004) with
plain Python lists of ``(row, col)`` tuples, its own BFS and an explicit loop over
conflict rounds, so that ``test_core_reference.py`` can check the vectorized core against
it robot by robot. Nothing here is imported by the package.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

WAIT = 4
MOVES = {0: (-1, 0), 1: (1, 0), 2: (0, -1), 3: (0, 1), 4: (0, 0)}  # Up, Down, Left, Right, Wait

Cell = tuple[int, int]


def bfs_distances(obstacles: list[list[bool]], goal: Cell) -> dict[Cell, int]:
    """Shortest 4-neighbour path length from every reachable free cell to ``goal``."""
    h, w = len(obstacles), len(obstacles[0])
    dist = {goal: 0}
    queue = deque([goal])
    while queue:
        r, c = queue.popleft()
        for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            nr, nc = r + dr, c + dc
            if 0 <= nr < h and 0 <= nc < w and not obstacles[nr][nc] and (nr, nc) not in dist:
                dist[(nr, nc)] = dist[(r, c)] + 1
                queue.append((nr, nc))
    return dist


@dataclass
class Episode:
    pos: list[Cell]
    goal: list[Cell]
    done: list[bool]
    ended: bool = False
    dist: list[dict[Cell, int]] = field(default_factory=list)


@dataclass
class RefStep:
    """One episode's step, per robot (lists of length N) plus the episode flags."""

    pos: list[Cell]
    collision: list[bool]
    invalid: list[bool]
    reached: list[bool]
    active: list[bool]
    progress: list[float]
    goal_bonus: list[float]
    collision_penalty: list[float]
    time_penalty: list[float]
    reward: float
    terminated: bool
    truncated: bool
    rounds: int  # conflict-resolution rounds that found a conflict


class ReferenceCore:
    """B independent episodes stepped one robot at a time."""

    def __init__(
        self, obstacles: list[list[bool]], horizon: int, on_goal: str,
        weights: tuple[float, float, float, float],
    ) -> None:
        self.obstacles = obstacles
        self.h, self.w = len(obstacles), len(obstacles[0])
        self.horizon = horizon
        self.remove = on_goal == "remove"
        self.q_p, self.q_g, self.q_c, self.q_tau = weights
        self._fields: dict[Cell, dict[Cell, int]] = {}

    def distance(self, cell: Cell, goal: Cell) -> int:
        if goal not in self._fields:
            self._fields[goal] = bfs_distances(self.obstacles, goal)
        return self._fields[goal][cell]

    def reset(self, starts: list[list[Cell]], goals: list[list[Cell]]) -> None:
        self.t = 0
        self.episodes = [
            Episode(pos=list(s), goal=list(g), done=[p == q for p, q in zip(s, g, strict=True)])
            for s, g in zip(starts, goals, strict=True)
        ]

    def free(self, cell: Cell) -> bool:
        r, c = cell
        return 0 <= r < self.h and 0 <= c < self.w and not self.obstacles[r][c]

    def step(self, actions: list[list[int]]) -> list[RefStep]:
        self.t += 1
        return [self._step_episode(ep, acts) for ep, acts in zip(self.episodes, actions, strict=True)]

    def _step_episode(self, ep: Episode, acts: list[int]) -> RefStep:
        n = len(ep.pos)
        robots = range(n)
        active = [not ep.ended and not ep.done[i] for i in robots]
        act = [acts[i] if active[i] else WAIT for i in robots]

        # Intended cells; a move into a shelf or off the grid stays and is invalid.
        nxt: list[Cell] = []
        invalid: list[bool] = []
        for i in robots:
            r, c = ep.pos[i]
            dr, dc = MOVES[act[i]]
            target = (r + dr, c + dc)
            if self.free(target):
                nxt.append(target)
                invalid.append(False)
            else:
                nxt.append(ep.pos[i])
                invalid.append(act[i] != WAIT)

        # Robots that occupy a cell: all of them, except completed ones under "remove".
        on_floor = [i for i in robots if not (self.remove and ep.done[i])]
        involved = [False] * n
        rounds = 0
        while True:
            conflict = set()
            for i in on_floor:
                for j in on_floor:
                    if i == j:
                        continue
                    if nxt[i] == nxt[j]:  # vertex conflict (also: entering a stayer's cell)
                        conflict.add(i)
                    if nxt[i] == ep.pos[j] and nxt[j] == ep.pos[i]:  # swap
                        conflict.add(i)
            if not conflict:
                break
            rounds += 1
            moved_back = False
            for i in conflict:
                involved[i] = True
                if nxt[i] != ep.pos[i]:
                    nxt[i] = ep.pos[i]
                    moved_back = True
            assert moved_back, "a conflict among robots that all stay cannot happen"
        new_pos = [nxt[i] if i in on_floor else ep.pos[i] for i in robots]
        floor_cells = [new_pos[i] for i in on_floor]
        assert len(set(floor_cells)) == len(floor_cells), "two robots share a cell"

        # eq:reward. A completed robot's terms are all zero (docs/decisions/0004).
        collision = [involved[i] and active[i] for i in robots]
        reached = [active[i] and new_pos[i] == ep.goal[i] for i in robots]
        done = [ep.done[i] or reached[i] for i in robots]
        progress = [
            self.q_p * (self.distance(ep.pos[i], ep.goal[i]) - self.distance(new_pos[i], ep.goal[i]))
            for i in robots
        ]
        goal_bonus = [self.q_g if reached[i] else 0.0 for i in robots]
        collision_penalty = [-self.q_c if collision[i] else 0.0 for i in robots]
        time_penalty = [-self.q_tau if active[i] and not done[i] else 0.0 for i in robots]
        total = 0.0
        for i in robots:
            total += progress[i] + goal_bonus[i] + collision_penalty[i] + time_penalty[i]

        running = not ep.ended
        terminated = running and all(done)
        truncated = running and not terminated and self.t >= self.horizon
        ep.pos, ep.done = new_pos, done
        ep.ended = ep.ended or terminated or truncated
        return RefStep(
            pos=new_pos, collision=collision, invalid=[invalid[i] and active[i] for i in robots],
            reached=reached, active=active, progress=progress, goal_bonus=goal_bonus,
            collision_penalty=collision_penalty, time_penalty=time_penalty, reward=total / n,
            terminated=terminated, truncated=truncated, rounds=rounds,
        )
