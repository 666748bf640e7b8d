"""Rendering of warehouse states as RGB frames, ANSI text and GIF files.

Pure functions of arrays, shared by the PettingZoo adapter (``render_mode``: "human"
prints ``render_ansi`` frames with ``show_in_terminal``) and by ``bench replay``: nothing here knows
about the core or the env. Positions are (row, col)
pairs; per-robot flags are (N,) bool arrays. Frames are drawn with numpy fancy indexing
(no Python loop over robots, no matplotlib).

Frame legend (``render_rgb``):

* shelves/walls dark grey, free cells white with a faint grid;
* robot i: a filled square in the colour of its group (``PALETTE``, cycling after 10);
  finished robots that stay on the floor (``on_goal="stay"``) are drawn pale;
* goal of an unfinished robot: a small outlined square in the robot's colour;
* collision this step: red border; control corrected by a safety filter: black inner
  border;
* optional link strip above the grid (when ``links`` is given), one segment per receiving
  group z: a swatch of z's colour, then one cell per sending group z' != z -- the sender's
  colour if A_t^{z',z} delivered, red if the message was lost, light grey if z' -> z is
  not an edge of the communication graph.
"""
from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

import numpy as np

from envs.atomic import atomic_path
from envs.errors import BenchError

# Ten group colours (tab10 without red, which marks collisions and lost links).
PALETTE = np.array(
    [
        (31, 119, 180),  # blue
        (255, 127, 14),  # orange
        (44, 160, 44),  # green
        (148, 103, 189),  # purple
        (140, 86, 75),  # brown
        (227, 119, 194),  # pink
        (188, 189, 34),  # olive
        (23, 190, 207),  # cyan
        (31, 51, 110),  # navy
        (255, 200, 40),  # gold
    ],
    dtype=np.uint8,
)
SHELF = np.array((64, 64, 64), np.uint8)
FREE = np.array((255, 255, 255), np.uint8)
GRID = np.array((232, 232, 232), np.uint8)
RED = np.array((220, 20, 20), np.uint8)
BLACK = np.array((0, 0, 0), np.uint8)
NON_EDGE = np.array((200, 200, 200), np.uint8)
STRIP_BG = np.array((245, 245, 245), np.uint8)


def group_colors(groups: np.ndarray) -> np.ndarray:
    """(N, 3) uint8 colour of each robot from its (N,) group index."""
    return PALETTE[np.asarray(groups, dtype=np.int64) % len(PALETTE)]


def default_cell_px(shape: tuple[int, int]) -> int:
    """Pixels per grid cell so the longer side is about 480 px (2..16)."""
    return int(np.clip(480 // max(shape), 2, 16))


def _ring(s: int, inset: int, width: int) -> np.ndarray:
    """(s, s) bool: a square outline ``width`` px thick, ``inset`` px from the cell edge."""
    m = np.zeros((s, s), dtype=bool)
    lo, hi = inset, s - inset
    if hi - lo <= 0:
        return m
    m[lo:hi, lo:hi] = True
    w = min(width, (hi - lo) // 2)
    if w > 0 and hi - lo > 2 * w:
        m[lo + w : hi - w, lo + w : hi - w] = False
    return m


def _box(s: int, inset: int) -> np.ndarray:
    m = np.zeros((s, s), dtype=bool)
    lo, hi = min(inset, (s - 1) // 2), s - min(inset, (s - 1) // 2)
    m[lo:hi, lo:hi] = True
    return m


def _stamp(frame: np.ndarray, rc: np.ndarray, s: int, top: int, mask: np.ndarray,
           colors: np.ndarray) -> None:
    """Paint ``mask`` ((s, s) bool) in each cell of ``rc`` ((K, 2)) with (K, 3) colours."""
    if len(rc) == 0 or not mask.any():
        return
    dy, dx = np.nonzero(mask)
    rows = top + rc[:, 0:1] * s + dy[None, :]  # (K, P)
    cols = rc[:, 1:2] * s + dx[None, :]
    frame[rows, cols] = np.broadcast_to(colors[:, None, :], rows.shape + (3,))


def _flag(x: np.ndarray | None, n: int, default: bool) -> np.ndarray:
    if x is None:
        return np.full(n, default, dtype=bool)
    x = np.asarray(x, dtype=bool).reshape(-1)
    if x.shape != (n,):
        raise BenchError(f"render: per-robot flags must have shape ({n},), got {x.shape}")
    return x


def _strip_geometry(z: int, width_px: int, cell_px: int) -> tuple[int, int, int]:
    """Link-strip cell size, gap after the swatch and gap between segments (pixels)."""
    for u in range(max(cell_px, 1), 0, -1):
        small, big = max(1, u // 2), u
        if z * z * u + z * small + (z - 1) * big <= width_px - 2:
            return u, small, big
    return 1, 1, 1  # does not fit: segments that overflow are clipped


def link_strip(links: np.ndarray, width_px: int, cell_px: int,
               adjacency: np.ndarray | None = None) -> np.ndarray:
    """(h, width_px, 3) uint8 strip showing which inter-group links delivered.

    ``links`` is (Z, Z) bool A_t[z', z] (sender z', receiver z); ``adjacency`` (Z, Z) bool
    marks the edges of the communication graph (default: all pairs z' != z).
    """
    links = np.asarray(links, dtype=bool)
    z = links.shape[0]
    if links.shape != (z, z):
        raise BenchError(f"render: links must be (Z, Z), got {links.shape}")
    adj = ~np.eye(z, dtype=bool) if adjacency is None else np.asarray(adjacency, dtype=bool)
    u, small, big = _strip_geometry(z, width_px, cell_px)
    strip = np.empty((u + 2, width_px, 3), np.uint8)
    strip[:] = STRIP_BG
    x = 1
    for recv in range(z):  # Z <= a few dozen: a loop over groups, not robots
        cells = [PALETTE[recv % len(PALETTE)]]
        for send in range(z):
            if send == recv:
                continue
            if not adj[send, recv]:
                cells.append(NON_EDGE)
            else:
                cells.append(PALETTE[send % len(PALETTE)] if links[send, recv] else RED)
        for k, color in enumerate(cells):
            if x + u > width_px:
                return strip
            strip[1 : 1 + u, x : x + u] = color
            x += u + (small if k == 0 else 0)
        x += big
    return strip


def render_rgb(
    layout: object,
    pos_rc: np.ndarray,
    goals_rc: np.ndarray,
    groups: np.ndarray,
    *,
    done: np.ndarray | None = None,
    on_floor: np.ndarray | None = None,
    collision: np.ndarray | None = None,
    corrected: np.ndarray | None = None,
    links: np.ndarray | None = None,
    adjacency: np.ndarray | None = None,
    cell_px: int | None = None,
) -> np.ndarray:
    """One RGB frame, (S + H * s, W * s, 3) uint8 with s = ``cell_px``.

    ``layout`` is a ``Layout`` or an (H, W) bool obstacle array. ``pos_rc`` and
    ``goals_rc`` are (N, 2) (row, col); ``groups`` (N,) group index. Optional (N,) bool:
    ``done`` (task completed; its goal is no longer drawn), ``on_floor`` (robot occupies
    a cell; default: not done, as with ``on_goal="remove"``), ``collision`` (red border),
    ``corrected`` (black border: the safety filter changed its control). ``links``
    ((Z, Z) bool, A_t[z', z]) adds a strip S px tall on top (S = 0 without it).
    """
    obstacles = np.asarray(getattr(layout, "obstacles", layout), dtype=bool)
    if obstacles.ndim != 2:
        raise BenchError(f"render: obstacle grid must be 2-D, got shape {obstacles.shape}")
    h, w = obstacles.shape
    s = default_cell_px((h, w)) if cell_px is None else int(cell_px)
    if s < 1:
        raise BenchError(f"render: cell_px must be >= 1, got {s}")
    pos = np.asarray(pos_rc, dtype=np.int64).reshape(-1, 2)
    goals = np.asarray(goals_rc, dtype=np.int64).reshape(-1, 2)
    n = len(pos)
    if goals.shape != (n, 2) or np.shape(groups) != (n,):
        raise BenchError(
            f"render: pos_rc {pos.shape}, goals_rc {goals.shape} and groups {np.shape(groups)} "
            "must describe the same robots"
        )
    done_ = _flag(done, n, False)
    floor = ~done_ if on_floor is None else _flag(on_floor, n, True)
    color = group_colors(groups)

    # Background: one colour per cell, blown up to s x s pixels, plus a faint grid.
    cell_rgb = np.where(obstacles[..., None], SHELF, FREE)
    grid = np.repeat(np.repeat(cell_rgb, s, axis=0), s, axis=1)
    if s >= 6:
        line = np.zeros((h * s, w * s), dtype=bool)
        line[::s, :] = True
        line[:, ::s] = True
        grid[line & ~np.repeat(np.repeat(obstacles, s, 0), s, 1)] = GRID
    strip = None
    if links is not None:
        strip = link_strip(links, w * s, s, adjacency)
    top = 0 if strip is None else strip.shape[0]
    frame = np.empty((top + h * s, w * s, 3), np.uint8)
    frame[top:] = grid
    if strip is not None:
        frame[:top] = strip

    # Goals of unfinished robots, then robots on top of them.
    open_goal = ~done_
    goal_mask = _ring(s, max(1, s // 4), max(1, s // 8)) if s >= 4 else _box(s, 0)
    _stamp(frame, goals[open_goal], s, top, goal_mask, color[open_goal])
    body = _box(s, 1 if s >= 4 else 0)
    pale = (color.astype(np.int16) + 2 * 255) // 3
    rcol = np.where(done_[:, None], pale.astype(np.uint8), color)
    _stamp(frame, pos[floor], s, top, body, rcol[floor])
    border = max(1, s // 8)
    if corrected is not None:
        sel = _flag(corrected, n, False) & floor
        mask = _ring(s, border + 1, border) if s >= 6 else _ring(s, 0, 1)
        _stamp(frame, pos[sel], s, top, mask, np.broadcast_to(BLACK, (int(sel.sum()), 3)))
    if collision is not None:
        sel = _flag(collision, n, False) & floor
        _stamp(frame, pos[sel], s, top, _ring(s, 0, border),
               np.broadcast_to(RED, (int(sel.sum()), 3)))
    return frame


def render_ansi(
    layout: object,
    pos_rc: np.ndarray,
    goals_rc: np.ndarray,
    groups: np.ndarray,
    *,
    done: np.ndarray | None = None,
    on_floor: np.ndarray | None = None,
    collision: np.ndarray | None = None,
    header: str | None = None,
) -> str:
    """A text grid: ``@`` shelf, ``.`` free, robots as their group letter (``A``, ``B``,
    ...), goals of unfinished robots in lower case, finished robots on the floor ``+``,
    robots in collision ``!``. Arguments as in ``render_rgb``; ``header`` is a first line.
    """
    obstacles = np.asarray(getattr(layout, "obstacles", layout), dtype=bool)
    pos = np.asarray(pos_rc, dtype=np.int64).reshape(-1, 2)
    goals = np.asarray(goals_rc, dtype=np.int64).reshape(-1, 2)
    n = len(pos)
    done_ = _flag(done, n, False)
    floor = ~done_ if on_floor is None else _flag(on_floor, n, True)
    coll = _flag(collision, n, False)
    letters = np.array([chr(ord("A") + k) for k in range(26)])
    g = np.asarray(groups, dtype=np.int64) % 26
    chars = np.where(obstacles, "@", ".").astype("<U1")
    chars[goals[~done_, 0], goals[~done_, 1]] = np.char.lower(letters[g[~done_]])
    robot = np.where(done_, "+", np.where(coll, "!", letters[g]))
    chars[pos[floor, 0], pos[floor, 1]] = robot[floor]
    lines = ["".join(row) for row in chars]
    if header:
        lines.insert(0, header)
    return "\n".join(lines)


CLEAR_HOME = "\x1b[H\x1b[2J"  # ANSI: cursor to the top left, clear the screen


def show_in_terminal(text: str, stream: TextIO) -> None:
    """Print one ``render_ansi`` frame for ``render_mode="human"``.

    On a terminal (``stream.isatty()``) the screen is cleared first, so successive frames
    replace each other in place like an animation; into a pipe or a log file frames are
    simply appended, separated by a blank line.
    """
    tty = bool(getattr(stream, "isatty", lambda: False)())
    stream.write((CLEAR_HOME if tty else "") + text + ("\n" if tty else "\n\n"))
    stream.flush()


def write_gif(frames: Sequence[np.ndarray] | np.ndarray, path: str | os.PathLike[str],
              fps: float = 8.0) -> Path:
    """Write (T, H, W, 3) uint8 frames as a looping GIF, atomically (envs/atomic.py).

    GIF encoders merge identical consecutive frames; so that the file keeps one frame per
    step, the corner pixel of a frame equal to its predecessor is inverted.
    """
    import imageio.v3 as iio

    path = Path(path)
    if len(frames) == 0:
        raise BenchError(f"write_gif {str(path)!r}: no frames to write")
    stack = np.array(frames, dtype=np.uint8, copy=True)
    if stack.ndim != 4 or stack.shape[-1] != 3:
        raise BenchError(f"write_gif {str(path)!r}: frames must be (T, H, W, 3), got {stack.shape}")
    for t in range(1, len(stack)):
        if np.array_equal(stack[t], stack[t - 1]):
            stack[t, 0, 0] = 255 - stack[t, 0, 0]
    with atomic_path(path) as tmp:
        iio.imwrite(tmp, stack, extension=".gif", duration=int(round(1000 / fps)), loop=0)
    return path
