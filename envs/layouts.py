"""Warehouse layouts: a boolean obstacle grid, its free cells P and the move table.

Sources: a parametric warehouse generator (shelf blocks, aisles, cross-aisles and open
crossing regions, as in the paper's Sec. IV), named presets sized for 20..100 robots,
MovingAI ``.map`` files and ASCII art. Positions inside the project are *cell indices*
into ``Layout.cells`` (row-major order of the free cells); ``(row, col)`` appears only at
the user-facing edges (PettingZoo infos, explicit scenarios, rendering).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
from scipy import ndimage

from envs.actions import DELTAS, N_ACTIONS
from envs.errors import BenchError

FREE_CHARS = frozenset(".GS")  # MovingAI: passable terrain
BLOCKED_CHARS = frozenset("@OTW")  # out of bounds, trees, water: not traversable here


@dataclass(frozen=True, eq=False)
class Layout:
    """A static warehouse floor.

    ``obstacles`` is (H, W) bool, True where a shelf or wall stands. Free cells form the
    feasible position set P of the paper; they are numbered 0..F-1 in row-major order.
    """

    name: str
    obstacles: np.ndarray = field(repr=False)  # (H, W) bool

    def __post_init__(self) -> None:
        obs = np.ascontiguousarray(self.obstacles, dtype=bool)
        if obs.ndim != 2 or obs.shape[0] < 1 or obs.shape[1] < 1:
            raise BenchError(f"layout {self.name!r}: obstacle grid must be 2-D and non-empty")
        obs.setflags(write=False)
        object.__setattr__(self, "obstacles", obs)

    @property
    def shape(self) -> tuple[int, int]:
        return self.obstacles.shape

    @cached_property
    def cells(self) -> np.ndarray:
        """(F, 2) int64 (row, col) of every free cell, row-major."""
        return np.argwhere(~self.obstacles).astype(np.int64)

    @cached_property
    def float_cells(self) -> np.ndarray:
        """(F, 2) float32 ``cells`` (for observation features)."""
        out = self.cells.astype(np.float32)
        out.setflags(write=False)
        return out

    @cached_property
    def float_shape(self) -> np.ndarray:
        """(2,) float32 (H, W) (for observation features)."""
        out = np.array(self.shape, dtype=np.float32)
        out.setflags(write=False)
        return out

    @property
    def n_free(self) -> int:
        return int(self.cells.shape[0])

    @cached_property
    def cell_index(self) -> np.ndarray:
        """(H, W) int64: free-cell index of each grid cell, -1 on obstacles."""
        idx = np.full(self.shape, -1, dtype=np.int64)
        idx[self.cells[:, 0], self.cells[:, 1]] = np.arange(self.n_free)
        return idx

    @cached_property
    def next_cell(self) -> np.ndarray:
        """(F, 5) int64: cell reached by each action; the same cell if the move is blocked.

        A move into a shelf or off the grid leaves the robot in place (SPEC 2).
        """
        h, w = self.shape
        tgt = self.cells[:, None, :] + DELTAS[None, :, :]  # (F, 5, 2)
        inside = (tgt[..., 0] >= 0) & (tgt[..., 0] < h) & (tgt[..., 1] >= 0) & (tgt[..., 1] < w)
        r = np.clip(tgt[..., 0], 0, h - 1)
        c = np.clip(tgt[..., 1], 0, w - 1)
        nxt = np.where(inside, self.cell_index[r, c], -1)
        stay = np.broadcast_to(np.arange(self.n_free)[:, None], nxt.shape)
        out = np.where(nxt >= 0, nxt, stay)
        out.setflags(write=False)
        return out

    @cached_property
    def move_valid(self) -> np.ndarray:
        """(F, 5) bool: the action changes the cell (Wait counts as valid)."""
        ok = self.next_cell != np.arange(self.n_free)[:, None]
        ok[:, N_ACTIONS - 1] = True
        ok.setflags(write=False)
        return ok

    @cached_property
    def components(self) -> np.ndarray:
        """(F,) int64 connected-component label (4-neighbourhood) of each free cell."""
        labels, _ = ndimage.label(~self.obstacles)
        return labels[self.cells[:, 0], self.cells[:, 1]].astype(np.int64)

    def to_index(self, rc: np.ndarray, what: str = "position") -> np.ndarray:
        """Map (..., 2) (row, col) to free-cell indices; a clear error for bad cells."""
        rc = np.asarray(rc, dtype=np.int64)
        if rc.ndim < 1 or rc.shape[-1] != 2:
            raise BenchError(f"{what}: expected (row, col) pairs, got shape {rc.shape}")
        h, w = self.shape
        r, c = rc[..., 0], rc[..., 1]
        inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
        if not inside.all():
            bad = tuple(int(v) for v in rc[~inside][0])
            raise BenchError(f"{what} {bad} lies outside the {h}x{w} layout {self.name!r}")
        idx = self.cell_index[r, c]
        if (idx < 0).any():
            bad = tuple(int(v) for v in rc[idx < 0][0])
            raise BenchError(f"{what} {bad} is an obstacle in layout {self.name!r}")
        return idx

    def to_ascii(self) -> str:
        return "\n".join("".join("@" if o else "." for o in row) for row in self.obstacles)


def from_ascii(text: str, name: str = "ascii") -> Layout:
    """Build a layout from ASCII rows: ``.`` (or space) free, ``@``/``#``/``T`` blocked."""
    rows = [ln.rstrip("\n") for ln in text.strip("\n").splitlines()]
    if not rows:
        raise BenchError(f"layout {name!r}: empty ASCII layout")
    width = max(len(r) for r in rows)
    grid = np.zeros((len(rows), width), dtype=bool)
    for i, row in enumerate(rows):
        for j, ch in enumerate(row.ljust(width, "@")):
            if ch in ". GS":
                continue
            if ch in "@#TOW":
                grid[i, j] = True
            else:
                raise BenchError(f"layout {name!r}: unknown character {ch!r} at row {i}, col {j}")
    return Layout(name, grid)


def load_movingai(path: str | Path) -> Layout:
    """Load a MovingAI benchmark ``.map`` file (``type``, ``height``, ``width``, ``map``)."""
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except OSError as exc:
        raise BenchError(f"map file {str(path)!r}: cannot read ({exc.strerror})") from None
    header: dict[str, str] = {}
    i = 0
    while i < len(lines) and lines[i].strip().lower() != "map":
        parts = lines[i].split()
        if len(parts) == 2:
            header[parts[0].lower()] = parts[1]
        elif parts:
            raise BenchError(f"map file {str(path)!r}, line {i + 1}: malformed header {lines[i]!r}")
        i += 1
    if i == len(lines):
        raise BenchError(f"map file {str(path)!r}: no 'map' line (not a MovingAI .map file)")
    try:
        height, width = int(header["height"]), int(header["width"])
    except (KeyError, ValueError):
        raise BenchError(f"map file {str(path)!r}: header needs integer 'height' and 'width'") from None
    body = lines[i + 1 : i + 1 + height]
    if len(body) != height:
        raise BenchError(f"map file {str(path)!r}: expected {height} grid rows, found {len(body)}")
    grid = np.zeros((height, width), dtype=bool)
    for r, row in enumerate(body):
        if len(row) != width:
            raise BenchError(
                f"map file {str(path)!r}, line {i + 2 + r}: row has {len(row)} cells, header says {width}"
            )
        for c, ch in enumerate(row):
            if ch in FREE_CHARS:
                continue
            if ch in BLOCKED_CHARS:
                grid[r, c] = True
            else:
                raise BenchError(
                    f"map file {str(path)!r}, line {i + 2 + r}, col {c}: unknown terrain {ch!r}"
                )
    return Layout(path.stem, grid)


def warehouse(
    block_rows: int,
    block_cols: int,
    shelf_h: int = 2,
    shelf_w: int = 5,
    aisle: int = 1,
    cross_every: int = 0,
    cross_width: int = 2,
    margin: int = 3,
    name: str = "warehouse",
) -> Layout:
    """Parametric warehouse (paper Sec. IV): shelf blocks between aisles, open crossings.

    ``block_rows x block_cols`` shelf blocks of ``shelf_h x shelf_w`` cells, separated by
    aisles ``aisle`` cells wide; every ``cross_every`` block columns a cross-aisle
    ``cross_width`` wide; open staging regions ``margin`` cells wide on the left and right
    (where flows cross), and a wall around everything.
    """
    for key, val in dict(block_rows=block_rows, block_cols=block_cols, shelf_h=shelf_h,
                         shelf_w=shelf_w, aisle=aisle).items():
        if val < 1:
            raise BenchError(f"warehouse generator: {key} must be >= 1, got {val}")
    col_widths: list[int] = []
    for j in range(block_cols):
        col_widths.append(shelf_w)
        if j < block_cols - 1:
            wide = cross_every > 0 and (j + 1) % cross_every == 0
            col_widths.append(cross_width if wide else aisle)
    inner_w = sum(col_widths) + 2 * margin
    inner_h = block_rows * shelf_h + (block_rows + 1) * aisle
    grid = np.zeros((inner_h + 2, inner_w + 2), dtype=bool)
    grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = True
    r = 1 + aisle
    for _ in range(block_rows):
        c = 1 + margin
        for k, wdt in enumerate(col_widths):
            if k % 2 == 0:
                grid[r : r + shelf_h, c : c + wdt] = True
            c += wdt
        r += shelf_h + aisle
    return Layout(name, grid)


# Presets sized for N robots: about 8-10 free cells per robot, Z=4 groups crossing in the
# open margins and cross-aisles. Free-cell counts are asserted in tests/envs/test_layouts.py.
PRESET_PARAMS: dict[str, dict[str, int]] = {
    "tiny": dict(block_rows=2, block_cols=2, shelf_w=3, margin=2),
    "wh20": dict(block_rows=3, block_cols=3, shelf_w=4, margin=3, cross_every=0),
    "wh40": dict(block_rows=4, block_cols=4, shelf_w=5, margin=3, cross_every=2),
    "wh60": dict(block_rows=5, block_cols=5, shelf_w=5, margin=3, cross_every=2),
    "wh80": dict(block_rows=5, block_cols=6, shelf_w=6, margin=4, cross_every=3),
    "wh90": dict(block_rows=6, block_cols=6, shelf_w=6, margin=4, cross_every=3),
    "wh100": dict(block_rows=6, block_cols=7, shelf_w=6, margin=4, cross_every=3),
}


def preset(name: str) -> Layout:
    if name not in PRESET_PARAMS:
        raise BenchError(
            f"unknown layout preset {name!r}; choose one of {', '.join(PRESET_PARAMS)} or a .map path"
        )
    return warehouse(name=name, **PRESET_PARAMS[name])


def preset_for(n_robots: int) -> str:
    """The smallest preset sized for at least ``n_robots`` robots."""
    for name in ("wh20", "wh40", "wh60", "wh80", "wh90", "wh100"):
        if int(name[2:]) >= n_robots:
            return name
    return "wh100"


MAPS_DIR = Path(__file__).parent / "maps"


def bundled_maps() -> list[str]:
    """Names of the MovingAI maps shipped in envs/maps/ (load them by name)."""
    return sorted(p.stem for p in MAPS_DIR.glob("*.map"))


_CACHE: dict[str, Layout] = {}


def load_layout(spec: str | Layout) -> Layout:
    """A preset name, a bundled map name, a MovingAI ``.map`` path or an ASCII ``.txt``; cached."""
    if isinstance(spec, Layout):
        return spec
    if spec not in _CACHE:
        if spec in PRESET_PARAMS:
            _CACHE[spec] = preset(spec)
        elif (MAPS_DIR / f"{spec}.map").is_file():
            _CACHE[spec] = load_movingai(MAPS_DIR / f"{spec}.map")
        elif spec.endswith(".map"):
            _CACHE[spec] = load_movingai(spec)
        elif spec.endswith(".txt"):
            try:
                text = Path(spec).read_text()
            except OSError as exc:
                raise BenchError(f"layout file {spec!r}: cannot read ({exc.strerror})") from None
            _CACHE[spec] = from_ascii(text, Path(spec).stem)
        else:
            raise BenchError(
                f"unknown layout {spec!r}: use a preset ({', '.join(PRESET_PARAMS)}), a bundled "
                f"map ({', '.join(bundled_maps())}), a MovingAI .map path or an ASCII .txt path"
            )
    return _CACHE[spec]
