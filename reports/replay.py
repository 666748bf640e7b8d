"""``write_replay``: an animated GIF of one evaluation episode, re-run from the checkpoint.

The episode is not stored step by step; it is re-run deterministically: the cell is rebuilt
from ``cells.parquet`` (``config_json``), its method from the registry with the cell's
seed, its trained state from ``checkpoints/<cell_id>.pt`` (``weights_only`` load), and
evaluation chunk ``episode // eval_chunk`` is run exactly as the bench's evaluator runs it
(``Method.evaluate(chunk, seed, execution)``, in one execution mode: argmax by default,
planner for PIBT), with hooks that record episode ``episode % eval_chunk`` step by step.
The recorded episode's metrics are checked against its stored evaluation row of the same
mode, so a GIF never shows an episode other than the one in the store.

Each frame (``envs.render.render_rgb``) shows robots coloured by group, the goals of
unfinished robots, collisions (red border), controls changed by the safety filter (black
inner border: proposed != executed) and, for methods with a group channel, a strip of the
inter-group links of that step (red = lost), with a caption: step, collisions,
corrections and lost links.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from algorithms.base import Method
from algorithms.common.episodes import Decision, EpisodeBatch
from algorithms.common.execution import ActionChoice
from algorithms.registry import method_class
from bench.cells import Cell
from bench.schema import EVAL_SCHEMA
from bench.store import RunStore, load_checkpoint, read_table
from envs.channel import LossProcess, comm_graph, group_assignment
from envs.core import StepResult
from envs.errors import BenchError
from envs.render import render_rgb, write_gif

CHECK_COLUMNS = ("team_return", "success_rate", "collision_rate", "steps")


@dataclass
class Step:
    """What one frame shows (robot arrays (N,), links (Z, Z) or None)."""

    t: int
    pos: np.ndarray  # free-cell index after the step
    done: np.ndarray
    on_floor: np.ndarray
    collision: np.ndarray
    corrected: np.ndarray
    links: np.ndarray | None


@dataclass
class Recorder:
    """Collects the steps of episode ``k`` of an evaluation batch (hooks below)."""

    k: int
    adjacency: np.ndarray  # (Z, Z) bool edges z' -> z of the communication graph
    steps: list[Step] = field(default_factory=list)
    goal: np.ndarray | None = None
    latest_links: np.ndarray | None = None
    pending: tuple[np.ndarray, np.ndarray | None, np.ndarray | None] | None = None

    def on_links(self, avail: np.ndarray) -> None:
        """Availability drawn by a loss process: kept (on graph edges) when it is group-level
        (B, Z, Z); robot-level processes (B, N, N) of other methods are ignored."""
        a = np.asarray(avail)
        z = len(self.adjacency)
        if a.ndim == 3 and a.shape[1:] == (z, z) and a.shape[0] > self.k:
            self.latest_links = a[self.k] & self.adjacency

    def begin(self, batch: EpisodeBatch) -> None:
        core, k = batch.core, self.k
        self.goal = core.goal[k].copy()
        n = core.n
        self.steps = [Step(0, core.pos[k].copy(), core.done[k].copy(), core.occupying[k].copy(),
                           np.zeros(n, bool), np.zeros(n, bool), None)]

    def decided(self, batch: EpisodeBatch, dec: Decision) -> None:
        if batch.core.ended[self.k]:
            self.pending = None
            return
        links = getattr(dec, "links", None)
        links = np.asarray(links)[self.k] if links is not None else self.latest_links
        proposed = None if dec.proposed is None else np.asarray(dec.proposed)[self.k].copy()
        self.pending = (np.asarray(dec.actions)[self.k].copy(), proposed, links)

    def observed(self, batch: EpisodeBatch, res: StepResult) -> None:
        if self.pending is None:
            return
        actions, proposed, links = self.pending
        core, k = batch.core, self.k
        active = res.active[k]
        corrected = (proposed != actions) & active if proposed is not None else np.zeros_like(active)
        self.steps.append(Step(len(self.steps), core.pos[k].copy(), core.done[k].copy(),
                               core.occupying[k].copy(), res.collision[k] & active, corrected,
                               None if links is None else np.asarray(links, dtype=bool)))
        self.pending = None


def _hook(method: Method, rec: Recorder) -> None:
    """Wrap the method's begin/decide/observe (instance attributes) to feed ``rec``."""
    begin, decide, observe = method.begin, method.decide, method.observe

    def _begin(batch: EpisodeBatch, choice: ActionChoice) -> Any:
        state = begin(batch, choice)
        rec.begin(batch)
        return state

    def _decide(batch: EpisodeBatch, state: Any, choice: ActionChoice) -> Decision:
        dec = decide(batch, state, choice)
        rec.decided(batch, dec)
        return dec

    def _observe(batch: EpisodeBatch, state: Any, result: Any) -> None:
        rec.observed(batch, result)
        observe(batch, state, result)

    method.begin, method.decide, method.observe = _begin, _decide, _observe  # type: ignore[method-assign]


def _run_recorded(method: Method, chunk: int, seed: int, rec: Recorder,
                  execution: str | None = None) -> list[dict[str, Any]]:
    """``method.evaluate(chunk, seed, execution)`` with every group-level loss draw
    reported to ``rec``."""
    original: Callable[[LossProcess], np.ndarray] = LossProcess.step

    def step(self: LossProcess) -> np.ndarray:
        out = original(self)
        rec.on_links(out)
        return out

    _hook(method, rec)
    LossProcess.step = step  # type: ignore[method-assign]
    try:
        return method.evaluate(chunk, seed, execution)
    finally:
        LossProcess.step = original  # type: ignore[method-assign]


def _caption(frame: np.ndarray, lines: list[str]) -> np.ndarray:
    """The frame with a white band of text lines on top (PIL's default font); the frame is
    padded with white on the right when the text is wider."""
    from PIL import Image, ImageDraw, ImageFont

    font = ImageFont.load_default()
    line_h = 12
    probe = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    width = max(frame.shape[1], *(int(probe.textlength(t, font=font)) + 6 for t in lines))
    band = Image.new("RGB", (width, line_h * len(lines) + 4), (255, 255, 255))
    draw = ImageDraw.Draw(band)
    for i, text in enumerate(lines):
        draw.text((3, 2 + i * line_h), text, fill=(0, 0, 0), font=font)
    body = np.pad(frame, ((0, 0), (0, width - frame.shape[1]), (0, 0)), constant_values=255)
    return np.concatenate([np.asarray(band, dtype=np.uint8), body], axis=0)


def render_steps(layout: Any, rec: Recorder, groups: np.ndarray, adjacency: np.ndarray,
                 horizon: int) -> list[np.ndarray]:
    """One captioned RGB frame per recorded step (the first shows the start)."""
    cells = layout.cells
    with_links = any(s.links is not None for s in rec.steps)
    z = len(adjacency)
    frames = []
    none = np.zeros_like(adjacency, dtype=bool)
    for s in rec.steps:
        # A frame before any message (the start) shows every link grey ("no message").
        links, adj = (s.links, adjacency) if s.links is not None else (
            (none, none) if with_links else (None, None))
        frame = render_rgb(layout, cells[s.pos], cells[rec.goal], groups, done=s.done,
                           on_floor=s.on_floor, collision=s.collision, corrected=s.corrected,
                           links=links, adjacency=adj)
        stats = f"collisions {int(s.collision.sum())} | corrected {int(s.corrected.sum())}"
        if s.links is not None:
            stats += f" | lost links {int((adjacency & ~s.links).sum())}/{int(adjacency.sum())}"
        head = f"t = {s.t}/{horizon} | done {int(s.done.sum())}/{len(s.done)} | Z = {z}"
        frames.append(_caption(frame, [head, stats]))
    width = max(f.shape[1] for f in frames)
    return [np.pad(f, ((0, 0), (0, width - f.shape[1]), (0, 0)), constant_values=255) for f in frames]


def _stored_row(rs: RunStore, cell_id: str, episode: int, execution: str) -> pd.Series | None:
    path = rs.eval_path(cell_id)
    if not path.exists():
        return None
    df = read_table(path, EVAL_SCHEMA).to_pandas()
    rows = df[(df["episode"] == episode) & (df["execution"] == execution)]
    return None if rows.empty else rows.iloc[-1]


def load_cell(rs: RunStore, cell_id: str) -> Cell:
    """The cell ``cell_id`` of the store, rebuilt from its canonical JSON."""
    cells = rs.read_cells()
    if cells is None:
        raise BenchError(f"no results store at {str(rs.root)!r}: cells.parquet not found")
    row = cells[cells["cell_id"] == cell_id]
    if row.empty:
        known = ", ".join(sorted(cells["cell_id"].astype(str))[:5])
        raise BenchError(f"no cell {cell_id!r} in {str(rs.root)!r} (cells include: {known}, ...)")
    return Cell.from_json(str(row.iloc[0]["config_json"]))


def write_replay(run_dir: Path | str, cell_id: str, episode: int, out: Path | str,
                 fps: float = 8.0, verify: bool = True, execution: str | None = None) -> Path:
    """Write evaluation episode ``episode`` of cell ``cell_id``, in execution mode
    ``execution`` (default: argmax, or planner for PIBT), as a GIF at ``out``.

    BenchError when the cell, its checkpoint (learned methods), the episode or the mode does
    not exist, or (``verify``) when the re-run does not reproduce the stored evaluation row.
    """
    rs = RunStore(run_dir)
    cell = load_cell(rs, cell_id)
    if not 0 <= int(episode) < cell.eval_episodes:
        raise BenchError(f"episode {episode} out of range: cell {cell_id} has {cell.eval_episodes} "
                         "evaluation episodes (0-based)")
    env = cell.to_env_config()
    method = method_class(cell.method)(env, cell.method_params().model_dump(mode="json"), seed=cell.seed)
    ckpt = rs.ckpt_path(cell_id)
    if ckpt.exists():
        method.load_state_dict(load_checkpoint(ckpt)["state"])
    elif method.learned:
        raise BenchError(f"cell {cell_id} has no checkpoint ({ckpt}); train it first (`bench run`)")
    size = method.params.eval_chunk
    chunk, k = divmod(int(episode), size)
    adjacency = comm_graph(env.groups, env.comm_graph)
    rec = Recorder(k, adjacency)
    modes = cell.execution_modes()
    choice = method.execution_choice(execution, cell.seed, chunk)
    if choice.name not in modes:
        raise BenchError(f"--execution {choice.name!r}: cell {cell_id} was evaluated in "
                         f"{', '.join(modes)}")
    rows = _run_recorded(method, chunk, cell.seed, rec, choice.name)
    if k >= len(rows):  # the last chunk may be cut short by eval_episodes
        raise BenchError(f"episode {episode} was not produced by evaluation chunk {chunk}")
    if verify:
        stored = _stored_row(rs, cell_id, int(episode), choice.name)
        if stored is not None:
            bad = [c for c in CHECK_COLUMNS
                   if not np.isclose(float(rows[k][c]), float(stored[c]), rtol=1e-6, atol=1e-9,
                                     equal_nan=True)]
            if bad:
                c = bad[0]
                raise BenchError(
                    f"replay of cell {cell_id} episode {episode} ({choice.name}) does not reproduce the stored "
                    f"evaluation ({c}: {rows[k][c]} re-run vs {stored[c]} stored); was the "
                    "checkpoint replaced after evaluation?")
    groups = group_assignment(env.n_robots, env.groups)
    frames = render_steps(method.layout, rec, groups, adjacency, env.horizon)
    return write_gif(frames, out, fps=fps)
