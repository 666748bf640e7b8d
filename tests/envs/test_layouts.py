"""Layouts: the real MovingAI map, BFS distances, presets, the move table, ASCII and errors."""
from __future__ import annotations

from collections import deque
from pathlib import Path

import numpy as np
import pytest

from envs.actions import Action
from envs.distances import UNREACHABLE, distance_cache
from envs.errors import BenchError
from envs.layouts import (
    MAPS_DIR,
    PRESET_PARAMS,
    from_ascii,
    load_layout,
    load_movingai,
    preset,
    preset_for,
)
from envs.scenarios import main_region, sample_scenarios

REAL_MAP = MAPS_DIR / "warehouse-10-20-10-2-1.map"  # bundled copy of the MovingAI map

# Free cells of each preset; they change only if the generator or its parameters change.
PRESET_FREE_CELLS = {
    "tiny": 53, "wh20": 128, "wh40": 230, "wh60": 342, "wh80": 440, "wh90": 518, "wh100": 598,
}


def hand_bfs(obstacles: np.ndarray, goal: tuple[int, int]) -> dict[tuple[int, int], int]:
    """Textbook BFS over (row, col), independent of the scipy-based DistanceCache."""
    h, w = obstacles.shape
    dist = {goal: 0}
    queue = deque([goal])
    while queue:
        r, c = queue.popleft()
        for nr, nc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
            if 0 <= nr < h and 0 <= nc < w and not obstacles[nr, nc] and (nr, nc) not in dist:
                dist[(nr, nc)] = dist[(r, c)] + 1
                queue.append((nr, nc))
    return dist


@pytest.fixture(scope="module")
def real_map():
    return load_layout(str(REAL_MAP))


def test_real_movingai_map_loads_with_its_free_cell_count(real_map) -> None:
    assert real_map.shape == (63, 161)
    assert real_map.n_free == 5699
    assert int((~real_map.obstacles).sum()) == 5699
    assert len(main_region(real_map)) == 5699  # one connected floor
    assert real_map.name == "warehouse-10-20-10-2-1"


def test_real_map_bfs_distances_match_a_hand_written_bfs(real_map) -> None:
    cache = distance_cache(real_map)
    rng = np.random.default_rng(0)
    for g in rng.choice(real_map.n_free, size=3, replace=False):
        want = hand_bfs(real_map.obstacles, tuple(int(v) for v in real_map.cells[g]))
        got = cache.field(int(g))
        assert len(want) == real_map.n_free
        expected = np.array([want[tuple(int(v) for v in rc)] for rc in real_map.cells])
        np.testing.assert_array_equal(got, expected)
        assert got.max() > 100  # shortest paths around shelves, far from Manhattan-trivial


def test_bfs_distance_goes_around_walls_and_marks_unreachable_cells() -> None:
    layout = from_ascii(".@..@.\n.@..@.\n....@.")
    field = distance_cache(layout).field(int(layout.to_index(np.array([0, 0]))))
    d = {tuple(int(v) for v in rc): int(x) for rc, x in zip(layout.cells, field, strict=True)}
    assert d[(0, 0)] == 0
    assert d[(0, 2)] == 6  # down, right under the wall, up again; Manhattan would say 2
    assert d[(0, 3)] == 7
    assert d[(0, 5)] == UNREACHABLE  # the right column is cut off by a wall column
    assert d == {k: v for k, v in hand_bfs(layout.obstacles, (0, 0)).items()} | {
        (r, 5): UNREACHABLE for r in range(3)
    }


@pytest.mark.parametrize("name", ["wh20", "wh40", "wh60", "wh80", "wh90", "wh100"])
def test_presets_have_room_for_their_robots(name: str) -> None:
    layout = preset(name)
    n = int(name[2:])
    assert layout.n_free == PRESET_FREE_CELLS[name]
    assert len(main_region(layout)) == layout.n_free  # no sealed-off pockets
    assert layout.n_free >= 5 * n  # about 6 free cells per robot (docs/decisions/0008)
    starts, goals = sample_scenarios(layout, n, 2, np.random.default_rng(1))
    assert starts.shape == goals.shape == (2, n)


def test_every_preset_is_listed_and_tiny_is_small() -> None:
    assert set(PRESET_PARAMS) == set(PRESET_FREE_CELLS)
    assert preset("tiny").n_free == PRESET_FREE_CELLS["tiny"]


def test_preset_for_picks_the_smallest_preset_that_fits() -> None:
    assert preset_for(1) == "wh20"
    assert preset_for(20) == "wh20"
    assert preset_for(21) == "wh40"
    assert preset_for(100) == "wh100"
    assert preset_for(500) == "wh100"


def test_presets_have_shelf_blocks_and_a_wall() -> None:
    layout = preset("wh40")
    obs = layout.obstacles
    assert obs[0].all() and obs[-1].all() and obs[:, 0].all() and obs[:, -1].all()
    inner = obs[1:-1, 1:-1]
    assert 0.2 < inner.mean() < 0.6  # shelves, not an empty room nor a solid block


def test_next_cell_moves_stays_when_blocked_and_waits() -> None:
    layout = from_ascii("..\n.@")
    idx = {tuple(int(v) for v in rc): i for i, rc in enumerate(layout.cells)}
    top_left, top_right, bottom_left = idx[(0, 0)], idx[(0, 1)], idx[(1, 0)]
    nxt = layout.next_cell
    assert nxt[top_left, Action.RIGHT] == top_right
    assert nxt[top_left, Action.DOWN] == bottom_left
    assert nxt[top_left, Action.UP] == top_left  # off the grid: stays
    assert nxt[top_left, Action.LEFT] == top_left
    assert nxt[top_right, Action.DOWN] == top_right  # into the shelf: stays
    assert nxt[bottom_left, Action.RIGHT] == bottom_left
    assert (nxt[:, Action.WAIT] == np.arange(layout.n_free)).all()
    valid = layout.move_valid
    assert valid[top_left].tolist() == [False, True, False, True, True]
    assert valid[top_right].tolist() == [False, False, True, False, True]


def test_ascii_layout_reads_walls_spaces_and_ragged_rows() -> None:
    layout = from_ascii("\n.#.\n. T\n..\n", name="hand")
    assert layout.name == "hand"
    assert layout.shape == (3, 3)
    assert layout.obstacles.tolist() == [
        [False, True, False],
        [False, False, True],
        [False, False, True],  # a short row is padded with walls
    ]
    assert layout.to_ascii() == ".@.\n..@\n..@"
    assert from_ascii(layout.to_ascii()).obstacles.tolist() == layout.obstacles.tolist()


def test_ascii_txt_file_loads_through_load_layout(tmp_path: Path) -> None:
    path = tmp_path / "room.txt"
    path.write_text("...\n.@.\n")
    layout = load_layout(str(path))
    assert layout.name == "room"
    assert layout.n_free == 5


def test_to_index_maps_row_col_and_rejects_walls_and_outside() -> None:
    layout = from_ascii("..\n.@")
    assert layout.to_index(np.array([[0, 0], [1, 0]])).tolist() == [0, 2]
    with pytest.raises(BenchError, match=r"\(1, 1\) is an obstacle"):
        layout.to_index(np.array([1, 1]), what="start")
    with pytest.raises(BenchError, match=r"\(5, 0\) lies outside the 2x2 layout"):
        layout.to_index(np.array([5, 0]))


def test_unknown_preset_names_the_choices() -> None:
    with pytest.raises(BenchError, match="unknown layout preset 'wh7'.*wh20"):
        preset("wh7")
    with pytest.raises(BenchError, match="unknown layout 'warehouse'.*MovingAI .map path"):
        load_layout("warehouse")


def test_unknown_ascii_character_is_rejected() -> None:
    with pytest.raises(BenchError, match=r"unknown character '\?' at row 1, col 2"):
        from_ascii("...\n..?")
    with pytest.raises(BenchError, match="empty ASCII layout"):
        from_ascii("\n\n")


def write_map(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "bad.map"
    path.write_text(text)
    return path


def test_movingai_map_without_map_line_is_rejected(tmp_path: Path) -> None:
    path = write_map(tmp_path, "type octile\nheight 2\nwidth 2\n")
    with pytest.raises(BenchError, match="bad.map.*no 'map' line"):
        load_movingai(path)


def test_movingai_map_without_any_header_is_rejected_at_line_1(tmp_path: Path) -> None:
    path = write_map(tmp_path, "..\n..\n")
    with pytest.raises(BenchError, match="bad.map', line 1: malformed header '..'"):
        load_movingai(path)


def test_movingai_map_without_height_is_rejected(tmp_path: Path) -> None:
    path = write_map(tmp_path, "type octile\nwidth 2\nmap\n..\n..\n")
    with pytest.raises(BenchError, match="header needs integer 'height' and 'width'"):
        load_movingai(path)


def test_movingai_map_with_a_malformed_header_line_is_rejected(tmp_path: Path) -> None:
    path = write_map(tmp_path, "type octile\nheight 2 extra\nwidth 2\nmap\n..\n..\n")
    with pytest.raises(BenchError, match="line 2: malformed header"):
        load_movingai(path)


def test_movingai_map_with_a_short_row_names_the_line(tmp_path: Path) -> None:
    path = write_map(tmp_path, "type octile\nheight 2\nwidth 3\nmap\n...\n..\n")
    with pytest.raises(BenchError, match="line 6: row has 2 cells, header says 3"):
        load_movingai(path)


def test_movingai_map_with_too_few_rows_is_rejected(tmp_path: Path) -> None:
    path = write_map(tmp_path, "type octile\nheight 3\nwidth 2\nmap\n..\n..\n")
    with pytest.raises(BenchError, match="expected 3 grid rows, found 2"):
        load_movingai(path)


def test_movingai_map_with_unknown_terrain_names_line_and_column(tmp_path: Path) -> None:
    path = write_map(tmp_path, "type octile\nheight 2\nwidth 2\nmap\n..\n.x\n")
    with pytest.raises(BenchError, match="line 6, col 1: unknown terrain 'x'"):
        load_movingai(path)


def test_movingai_terrain_letters_are_free_or_blocked(tmp_path: Path) -> None:
    path = write_map(tmp_path, "type octile\nheight 1\nwidth 7\nmap\n.GS@OTW\n")
    layout = load_movingai(path)
    assert layout.obstacles.tolist() == [[False, False, False, True, True, True, True]]


def test_missing_map_file_is_a_bench_error(tmp_path: Path) -> None:
    missing = tmp_path / "nope.map"
    with pytest.raises(BenchError, match="nope.map.*cannot read"):
        load_layout(str(missing))


def test_load_layout__bundled_map_by_name_equals_the_shared_file():
    from envs.layouts import bundled_maps, load_layout

    assert "warehouse-10-20-10-2-1" in bundled_maps()
    bundled = load_layout("warehouse-10-20-10-2-1")
    assert bundled.n_free == 5699
    assert (bundled.obstacles == load_layout(str(REAL_MAP)).obstacles).all()
