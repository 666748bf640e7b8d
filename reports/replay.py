"""``write_replay``: a GIF or MP4 of one evaluation episode, re-run from the checkpoint.

The episode is not stored step by step; it is re-run deterministically: the cell is rebuilt
from ``cells.parquet`` (``config_json``), its method from the registry with the cell's
seed, its trained state from ``checkpoints/<cell_id>.pt`` (``weights_only`` load), and
evaluation chunk ``episode // eval_chunk`` is run exactly as the bench's evaluator runs it
(``Method.evaluate(chunk, seed, execution)``, in one execution mode: argmax by default,
planner for PIBT), with an observer (the Method contract's hook, ``Recorder``) that keeps
episode ``episode % eval_chunk`` step by step.
The recorded episode's metrics are checked against its stored evaluation row of the same
mode, so a GIF never shows an episode other than the one in the store.

Each frame (reports/figures/replay_frames.py, grid by ``envs.render.render_rgb``, at least 800 px
wide) shows robots coloured by group, the goals of unfinished robots, collisions (red
border), controls changed by the safety filter (black inner border: proposed != executed)
and, for methods with a group channel, a row of the inter-group links of that step (red =
lost). A caption names the method, N, p, layout, cell id, episode and execution mode, then
the step's counters; a legend explains every mark. ``progress(phase, done, total)`` is
called while re-running, drawing and encoding. MP4 needs the optional ``imageio-ffmpeg``
package; without it ``--format mp4`` is one clear error before any work.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from algorithms.common.observer import StepRecord
from algorithms.registry import method_class
from bench.design.cells import Cell
from bench.store.checkpoints import load_checkpoint
from bench.store.run_store import RunStore, read_table
from bench.store.schema import EVAL_SCHEMA
from envs.channel import comm_graph, group_assignment
from envs.errors import BenchError
from envs.render import render_rgb, write_gif
from reports.figures.plotting import method_label
from reports.figures.replay_frames import (
    LegendSpec,
    compose,
    legend_panel,
    links_row,
    replay_cell_px,
)

CHECK_COLUMNS = ("team_return", "success_rate", "collision_rate", "steps")
FORMATS = ("gif", "mp4")
Progress = Callable[[str, int, int], None]  # (phase, done, total)


def _no_progress(_phase: str, _done: int, _total: int) -> None:
    return None


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
    """Observer (``Method.evaluate(..., observer=rec)``) that keeps the steps of episode
    ``k`` of the evaluation batch: one ``Step`` for the start, then one per step it runs."""

    k: int
    adjacency: np.ndarray  # (Z, Z) bool edges z' -> z of the communication graph
    steps: list[Step] = field(default_factory=list)
    goal: np.ndarray | None = None
    has_proposals: bool = False  # the method reported proposals (it has a safety filter)

    def __call__(self, rec: StepRecord) -> None:
        k = self.k
        if not self.steps:  # the first record: the start, before any control
            start = rec.before
            self.goal = rec.goal[k].copy()
            n = len(start.pos[k])
            self.steps = [Step(0, start.pos[k], start.done[k], start.on_floor[k],
                               np.zeros(n, bool), np.zeros(n, bool), None)]
        if not rec.running[k]:
            return
        self.has_proposals |= rec.has_proposals
        links = rec.group_links  # (B, Z', Z); (B, 0, 0) without a group channel
        active = rec.result.active[k]
        self.steps.append(Step(len(self.steps), rec.after.pos[k], rec.after.done[k], rec.after.on_floor[k],
                               rec.result.collision[k] & active, rec.corrected[k],
                               links[k] & self.adjacency if links.shape[1:] == self.adjacency.shape else None))


def render_steps(layout: Any, rec: Recorder, groups: np.ndarray, adjacency: np.ndarray,
                 horizon: int, title: str = "", progress: Progress = _no_progress) -> list[np.ndarray]:
    """One captioned, legended RGB frame per recorded step (the first shows the start);
    ``title`` is the caption's first line (method, N, p, cell, episode, execution)."""
    cells = layout.cells
    with_links = any(s.links is not None for s in rec.steps)
    z = len(adjacency)
    shape = np.asarray(getattr(layout, "obstacles", layout)).shape
    px = replay_cell_px(shape)
    width = max(shape[1] * px, 800)
    legend = legend_panel(width, LegendSpec(groups=z, links=with_links, corrections=rec.has_proposals))
    none = np.zeros_like(adjacency, dtype=bool)
    frames = []
    for i, s in enumerate(rec.steps):
        body = render_rgb(layout, cells[s.pos], cells[rec.goal], groups, done=s.done,
                          on_floor=s.on_floor, collision=s.collision, corrected=s.corrected, cell_px=px)
        stats = (f"t = {s.t}/{horizon}  |  done {int(s.done.sum())}/{len(s.done)}  |  "
                 f"collisions {int(s.collision.sum())}")
        if rec.has_proposals:
            stats += f"  |  corrected {int(s.corrected.sum())}"
        row = None
        if with_links:
            # A frame before any message (the start) shows every link grey ("no message").
            links, adj = (s.links, adjacency) if s.links is not None else (none, none)
            row = links_row(width, links, adj)
            stats += (f"  |  lost links {int((adjacency & ~s.links).sum())}/{int(adjacency.sum())}"
                      if s.links is not None else "  |  no message yet")
        frames.append(compose([(title, True), (stats, False)] if title else [(stats, False)], body, legend, row))
        progress("drawing frames", i + 1, len(rec.steps))
    height = max(f.shape[0] for f in frames)  # a wrapped caption may add a line
    return [np.pad(f, ((0, height - f.shape[0]), (0, 0), (0, 0)), constant_values=255) for f in frames]


def write_mp4(frames: list[np.ndarray], path: Path | str, fps: float = 8.0) -> Path:
    """Write frames as H.264 MP4 (yuv420p) atomically; frames are padded white to a multiple
    of 16 px. BenchError when ``imageio-ffmpeg`` is not installed."""
    from envs.atomic import atomic_path

    ffmpeg = require_mp4()
    path = Path(path)
    if not frames:
        raise BenchError(f"write_mp4 {str(path)!r}: no frames to write")
    h, w = frames[0].shape[:2]
    ph, pw = -(-h // 16) * 16, -(-w // 16) * 16
    with atomic_path(path, suffix=".mp4") as tmp:  # ffmpeg picks the container by the suffix
        writer = ffmpeg.write_frames(str(tmp), (pw, ph), fps=fps, codec="libx264", pix_fmt_out="yuv420p",
                                     macro_block_size=16, quality=8, ffmpeg_log_level="error")
        writer.send(None)
        for f in frames:
            writer.send(np.ascontiguousarray(np.pad(f, ((0, ph - h), (0, pw - w), (0, 0)), constant_values=255)))
        writer.close()
    return path


def require_mp4() -> Any:
    """The ``imageio_ffmpeg`` module, or BenchError saying how to get MP4 output."""
    try:
        import imageio_ffmpeg
    except ImportError:
        raise BenchError("--format mp4 needs the imageio-ffmpeg package, which is not installed "
                         "(pip install imageio-ffmpeg); use --format gif") from None
    return imageio_ffmpeg


@contextmanager
def replay_progress() -> Iterator[Progress]:
    """A ``progress`` callback for ``write_replay``: a rich bar per phase on an interactive
    stderr, else one line on stderr per phase start and end and every 25 % of the frames."""
    import os
    import sys

    if os.environ.get("CI", "").lower() in ("1", "true", "yes") or not sys.stderr.isatty():
        last: dict[str, int] = {}

        def lines(phase: str, done: int, total: int) -> None:
            quarter = 4 * done // max(total, 1)  # 0..4: start, each 25 %, end
            if last.get(phase) != quarter:
                last[phase] = quarter
                print(f"replay: {phase} {done}/{total}", file=sys.stderr, flush=True)

        yield lines
        return
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    tasks: dict[str, Any] = {}
    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  TextColumn("ETA"), TimeRemainingColumn(), transient=False) as bar:
        def update(phase: str, done: int, total: int) -> None:
            if phase not in tasks:
                tasks[phase] = bar.add_task(phase, total=total)
            bar.update(tasks[phase], completed=done, total=total)

        yield update


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
                 fps: float = 8.0, verify: bool = True, fmt: str = "gif",
                 progress: Progress = _no_progress, execution: str | None = None) -> Path:
    """Write evaluation episode ``episode`` of cell ``cell_id``, in execution mode
    ``execution`` (default: argmax, or planner for PIBT), as a GIF or MP4 (``fmt``) at ``out``.

    BenchError when the cell, its checkpoint (learned methods), the episode or the mode does
    not exist, when ``fmt`` is unknown or MP4 support is missing, or (``verify``) when the
    re-run does not reproduce the stored evaluation row.
    """
    if fmt not in FORMATS:
        raise BenchError(f"unknown replay format {fmt!r}; choose {' or '.join(FORMATS)}")
    if fmt == "mp4":
        require_mp4()  # fail before the re-run
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
    progress("re-running the episode", 0, 1)
    rows = method.evaluate(chunk, cell.seed, choice.name, observer=rec)
    progress("re-running the episode", 1, 1)
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
    title = (f"{method_label(cell.method)}  |  N={env.n_robots}  |  p={env.loss_p:g}  |  Z={env.groups}  |  "
             f"{cell.layout}  |  cell {cell_id}  |  episode {int(episode)}  |  execution {choice.name}")
    frames = render_steps(method.layout, rec, groups, adjacency, env.horizon, title, progress)
    progress(f"encoding {fmt}", 0, 1)
    path = write_mp4(frames, out, fps=fps) if fmt == "mp4" else write_gif(frames, out, fps=fps)
    progress(f"encoding {fmt}", 1, 1)
    return path
