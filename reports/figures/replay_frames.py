"""Readable replay frames: a captioned, legended picture of each step (``bench replay``).

Frames of 352 x 238 px with a bitmap font and no legend were unreadable. Here a frame is, top to
bottom: a caption band (method, N, p, cell id, episode, execution mode; then the step's
counters), the grid drawn by ``envs.render.render_rgb`` at ``replay_cell_px`` pixels per
cell (at least ``MIN_WIDTH`` px wide: 6 px cells, 966 px, for the 63 x 161 MovingAI map)
and a legend panel. Text uses matplotlib's bundled DejaVu Sans through PIL. The legend's
robot, goal and border swatches are drawn by ``render_rgb`` itself on a one-cell grid, so
they cannot drift from what the frames show.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from envs.render import NON_EDGE, PALETTE, RED, link_strip, render_rgb

MIN_WIDTH = 800  # px: frames at least this wide
MAX_CELL_PX = 96
WHITE = (255, 255, 255)
INK = (20, 20, 20)
MUTED = (90, 90, 90)


def replay_cell_px(shape: tuple[int, int]) -> int:
    """Pixels per grid cell so the grid is at least ``MIN_WIDTH`` wide: ceil(800 / W),
    at least 6 (room for the corrected-robot inner border), at most ``MAX_CELL_PX``."""
    return int(min(max(6, math.ceil(MIN_WIDTH / max(shape[1], 1))), MAX_CELL_PX))


@lru_cache(maxsize=8)
def font(size: int, bold: bool = False):  # noqa: ANN201 (PIL FreeTypeFont)
    """Matplotlib's bundled DejaVu Sans (always installed with matplotlib) at ``size`` px."""
    from matplotlib import font_manager
    from PIL import ImageFont

    props = font_manager.FontProperties(family="DejaVu Sans", weight="bold" if bold else "normal")
    return ImageFont.truetype(font_manager.findfont(props, fallback_to_default=True), size)


def text_px(width: int) -> int:
    """Caption font size for a frame ``width`` px wide (15 px at 800 px)."""
    return int(np.clip(width // 53, 12, 22))


def text_band(width: int, lines: Sequence[tuple[str, bool]], size: int,
              color: tuple[int, int, int] = INK) -> np.ndarray:
    """(h, width, 3) uint8 white band with ``lines`` of (text, bold), wrapped at words."""
    from PIL import Image, ImageDraw

    wrapped: list[tuple[str, bool]] = []
    for text, bold in lines:
        f = font(size, bold)
        words, cur = text.split(" "), ""
        for w in words:
            trial = f"{cur} {w}".strip()
            if cur and f.getlength(trial) > width - 2 * size // 2:
                wrapped.append((cur, bold))
                cur = w
            else:
                cur = trial
        wrapped.append((cur, bold))
    line_h = int(size * 1.35)
    img = Image.new("RGB", (width, line_h * len(wrapped) + size // 2), WHITE)
    draw = ImageDraw.Draw(img)
    for i, (text, bold) in enumerate(wrapped):
        draw.text((size // 2, size // 4 + i * line_h), text, fill=color, font=font(size, bold))
    return np.asarray(img, dtype=np.uint8)


def _swatch(s: int, group: int = 0, **flags: bool) -> np.ndarray:
    """(s, s, 3) one free cell drawn by ``render_rgb`` with one robot of ``group``."""
    on_floor = flags.pop("on_floor", True)
    at = np.zeros((1, 2), np.int64)  # the robot and its goal on the one cell
    return render_rgb(np.zeros((1, 1), bool), at, at, np.array([group]), cell_px=s,
                      on_floor=np.array([on_floor]),
                      **{k: np.array([v]) for k, v in flags.items()})


def _solid(s: int, color: np.ndarray) -> np.ndarray:
    out = np.empty((s, s, 3), np.uint8)
    out[:] = color
    out[0, :] = out[-1, :] = out[:, 0] = out[:, -1] = (160, 160, 160)
    return out


@dataclass(frozen=True)
class LegendSpec:
    groups: int  # Z
    links: bool  # the frames carry a link strip
    corrections: bool  # the method proposes controls a safety filter may change


def legend_items(spec: LegendSpec, s: int) -> list[tuple[np.ndarray, str]]:
    """(swatch (s, s, 3), label) of everything a frame may show."""
    items = [(_swatch(s, z), f"group {z}") for z in range(spec.groups)]
    items += [(_swatch(s, 0, on_floor=False), "goal of an unfinished robot"),
              (_swatch(s, 0, done=True), "finished robot (stays on its goal)"),
              (_swatch(s, 0, collision=True), "collision this step (red border)")]
    if spec.corrections:
        items.append((_swatch(s, 0, corrected=True), "control changed by the safety filter (black border)"))
    if spec.links:
        items += [(_solid(s, PALETTE[0]), "inter-group links: receiving group, then one cell per sender:"),
                  (_solid(s, PALETTE[1]), "message delivered (sender's colour)"),
                  (_solid(s, RED), "message lost"), (_solid(s, NON_EDGE), "not an edge of the graph")]
    return items


def legend_panel(width: int, spec: LegendSpec) -> np.ndarray:
    """(h, width, 3) uint8 legend: swatches with labels, wrapped into rows."""
    from PIL import Image, ImageDraw

    size = max(11, text_px(width) - 2)
    s = int(size * 1.3)
    f = font(size)
    pad = size // 2
    items = legend_items(spec, s)
    rows: list[list[tuple[np.ndarray, str, int]]] = [[]]
    x = pad
    for sw, label in items:
        w = s + pad // 2 + int(f.getlength(label)) + 2 * pad
        if rows[-1] and x + w > width:
            rows.append([])
            x = pad
        rows[-1].append((sw, label, x))
        x += w
    row_h = s + pad
    head = int(size * 1.5)
    img = Image.new("RGB", (width, head + row_h * len(rows) + pad), WHITE)
    draw = ImageDraw.Draw(img)
    draw.line([(0, 1), (width, 1)], fill=(200, 200, 200), width=1)
    draw.text((pad, pad // 2), "Legend", fill=INK, font=font(size, True))
    arr = np.asarray(img, dtype=np.uint8).copy()
    for r, row in enumerate(rows):
        y = head + r * row_h
        for sw, _label, x0 in row:
            arr[y:y + s, x0:x0 + s] = sw
    img = Image.fromarray(arr)
    draw = ImageDraw.Draw(img)
    for r, row in enumerate(rows):
        y = head + r * row_h
        for _sw, label, x0 in row:
            draw.text((x0 + s + pad // 2, y + (s - size) // 2 - 1), label, fill=MUTED, font=f)
    return np.asarray(img, dtype=np.uint8)


def links_row(width: int, links: np.ndarray, adjacency: np.ndarray) -> np.ndarray:
    """(h, width, 3) uint8: the label "links" and ``envs.render.link_strip`` drawn with
    cells as tall as the caption text (the frame's own strip uses grid-cell pixels, 6 px on
    the MovingAI map, too small to read)."""
    from PIL import Image, ImageDraw

    size = text_px(width)
    label = "inter-group links"
    f = font(size)
    lw = int(f.getlength(label)) + size
    strip = link_strip(links, width - lw - size // 2, size, adjacency)
    img = Image.new("RGB", (width, strip.shape[0] + 6), WHITE)
    ImageDraw.Draw(img).text((size // 2, (strip.shape[0] + 6 - size) // 2 - 1), label, fill=MUTED, font=f)
    arr = np.asarray(img, dtype=np.uint8).copy()
    arr[3:3 + strip.shape[0], lw:lw + strip.shape[1]] = strip
    return arr


def compose(caption: Sequence[tuple[str, bool]], body: np.ndarray, legend: np.ndarray,
            links: np.ndarray | None = None) -> np.ndarray:
    """Caption band, the link row (``links``: output of ``links_row``), the rendered grid
    (centred, white margins) and the legend, stacked."""
    width = legend.shape[1]
    band = text_band(width, caption, text_px(width))
    left = (width - body.shape[1]) // 2
    grid = np.full((body.shape[0] + 8, width, 3), 255, np.uint8)
    grid[4:-4, left:left + body.shape[1]] = body
    parts = [band] + ([links] if links is not None else []) + [grid, legend]
    return np.concatenate(parts, axis=0)
