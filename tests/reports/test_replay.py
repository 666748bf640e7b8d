"""write_replay re-runs one evaluation episode from the store and checkpoint and records
it frame by frame (reports/replay.py), and the frames are readable: width, legend, caption,
progress, MP4. Runtime: about 15 s (PIBT on the tiny layout)."""
from __future__ import annotations

from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pandas as pd
import pytest

import reports.replay as replay
from algorithms.common.episodes import Decision
from algorithms.pibt import PIBTMethod
from algorithms.registry import method_class
from bench.design.cells import Cell
from bench.store.run_store import RunStore
from bench.store.schema import SCHEMA_VERSION
from envs.actions import WAIT
from envs.channel import GroupChannel
from envs.errors import BenchError


def _store(run: Path, cls: type = PIBTMethod, eval_episodes: int = 4) -> tuple[Cell, list[dict]]:
    """A one-cell store: cells.parquet, the evaluation rows and a checkpoint, as the bench."""
    cell = Cell.make(method="pibt", n_robots=6, loss_p=0.5, groups=3, layout="tiny", episodes=0,
                     horizon=40, eval_episodes=eval_episodes, params={"eval_chunk": 2})
    rs = RunStore(run)
    rs.write_cells([{**cell.config_columns(), "grid": "t", "status": "done", "error": "",
                     "train_episodes_done": 0, "wall_s": 0.0, "peak_mem_mb": 0.0, "attempts": 1,
                     "versions_json": "{}", "schema_version": SCHEMA_VERSION}])
    m = cls(cell.to_env_config(), cell.method_params().model_dump(mode="json"), seed=cell.seed)
    rows = [r for c in range(eval_episodes // 2) for r in m.evaluate(c, cell.seed)]
    rs.write_eval(cell.cell_id, rows, {})
    rs.write_checkpoint(cell.cell_id, {"cell": cell.canonical_json(), "state": m.state_dict()})
    return cell, rows


def _frames(path: Path) -> np.ndarray:
    return iio.imread(path, index=None)[..., :3]


def test_write_replay__one_frame_per_step_of_the_stored_episode(tmp_path):
    cell, rows = _store(tmp_path)
    out = replay.write_replay(tmp_path, cell.cell_id, 3, tmp_path / "r.gif")
    frames = _frames(out)
    assert len(frames) == rows[3]["steps"] + 1  # the start, then one frame per step
    # a different episode of another chunk is a different animation
    other = _frames(replay.write_replay(tmp_path, cell.cell_id, 0, tmp_path / "r0.gif"))
    assert len(other) == rows[0]["steps"] + 1
    assert not (len(other) == len(frames) and np.array_equal(other, frames))


def test_write_replay__refuses_an_episode_that_does_not_match_the_store(tmp_path):
    cell, rows = _store(tmp_path)
    rows[3]["team_return"] += 1.0  # as if the checkpoint had changed since evaluation
    RunStore(tmp_path).write_eval(cell.cell_id, rows, {})
    with pytest.raises(BenchError, match="does not reproduce the stored evaluation"):
        replay.write_replay(tmp_path, cell.cell_id, 3, tmp_path / "r.gif")
    assert not (tmp_path / "r.gif").exists()


def test_write_replay__user_errors(tmp_path):
    cell, _ = _store(tmp_path)
    with pytest.raises(BenchError, match="no cell 'abc'"):
        replay.write_replay(tmp_path, "abc", 0, tmp_path / "r.gif")
    with pytest.raises(BenchError, match="out of range"):
        replay.write_replay(tmp_path, cell.cell_id, 4, tmp_path / "r.gif")
    with pytest.raises(BenchError, match="cells.parquet not found"):
        replay.write_replay(tmp_path / "none", cell.cell_id, 0, tmp_path / "r.gif")


class ChannelPIBT(PIBTMethod):
    """PIBT plus a group channel and a fake 'filter' that rewrites robot 0's proposal, so
    the recorder's links and corrections can be checked against what the method drew."""

    drawn: list[np.ndarray] = []

    def begin(self, batch, choice):
        state = super().begin(batch, choice)
        state.channel = GroupChannel(self.env, batch.core.batch, batch.rng.spawn(1)[0])
        return state

    def decide(self, batch, state, choice) -> Decision:
        dec = super().decide(batch, state, choice)
        avail = state.channel.step()
        type(self).drawn.append(avail.copy())
        proposed = dec.actions.copy()
        proposed[:, 0] = np.where(dec.actions[:, 0] == WAIT, 0, WAIT)  # always "corrected"
        return Decision(actions=dec.actions, proposed=proposed, payload=dec.payload, group_links=avail)


def test_recorder__links_and_corrections_are_those_of_the_episode(tmp_path, monkeypatch):
    monkeypatch.setattr(replay, "method_class",
                        lambda name: ChannelPIBT if name == "pibt" else method_class(name))
    cell, rows = _store(tmp_path, ChannelPIBT)
    k = 1  # episode 3 = chunk 1, slot 1
    env = cell.to_env_config()
    m = ChannelPIBT(env, cell.method_params().model_dump(mode="json"), seed=cell.seed)
    rec = replay.Recorder(k, ~np.eye(env.groups, dtype=bool))
    ChannelPIBT.drawn = []
    got = m.evaluate(1, cell.seed, observer=rec)
    pd.testing.assert_frame_equal(pd.DataFrame(got), pd.DataFrame(rows[2:4]))  # recording changes nothing
    steps = rec.steps[1:]
    assert len(steps) == rows[3]["steps"]
    for t, s in enumerate(steps):
        np.testing.assert_array_equal(s.links, ChannelPIBT.drawn[t][k])
        assert s.corrected[0] == (not rec.steps[t].done[0])  # active: unfinished before step t
        assert not s.corrected[1:].any()
    assert any((~s.links & ~np.eye(3, dtype=bool)).any() for s in steps)  # p = 0.5 loses links
    # rendered: a link strip above the grid makes frames taller than plain PIBT frames
    gif = _frames(replay.write_replay(tmp_path, cell.cell_id, 3, tmp_path / "c.gif"))
    monkeypatch.setattr(replay, "method_class", method_class)
    cell2, _ = _store(tmp_path / "plain")
    plain = _frames(replay.write_replay(tmp_path / "plain", cell2.cell_id, 3, tmp_path / "p.gif"))
    assert gif.shape[1] > plain.shape[1]


def _learned_store(run):
    """A one-cell decentralized store (untrained weights) evaluated in its three modes."""
    cell = Cell.make(method="decentralized", n_robots=6, loss_p=0.3, layout="tiny", episodes=0,
                     horizon=30, eval_episodes=4, params={"eval_chunk": 2})
    rs = RunStore(run)
    rs.write_cells([{**cell.config_columns(), "grid": "t", "status": "done", "error": "",
                     "train_episodes_done": 0, "wall_s": 0.0, "peak_mem_mb": 0.0, "attempts": 1,
                     "versions_json": "{}", "schema_version": SCHEMA_VERSION}])
    m = method_class("decentralized")(cell.to_env_config(), cell.method_params().model_dump(mode="json"),
                                      seed=cell.seed)
    rows = {mode: [r for c in range(2) for r in m.evaluate(c, cell.seed, mode)] for mode in cell.execution_modes()}
    rs.write_eval(cell.cell_id, [r for mode_rows in rows.values() for r in mode_rows], {})
    rs.write_checkpoint(cell.cell_id, {"cell": cell.canonical_json(), "state": m.state_dict()})
    return cell, rows


def test_write_replay__replays_the_stored_episode_of_the_chosen_execution_mode(tmp_path):
    cell, rows = _learned_store(tmp_path)
    assert rows["argmax"][1]["team_return"] != rows["sample@0.5"][1]["team_return"]
    for mode in ("argmax", "sample", "sample@0.5"):
        out = replay.write_replay(tmp_path, cell.cell_id, 1, tmp_path / f"{mode}.gif", execution=mode)
        assert len(_frames(out)) == rows[mode][1]["steps"] + 1, mode  # verified against its own row
    assert not np.array_equal(_frames(tmp_path / "argmax.gif"), _frames(tmp_path / "sample@0.5.gif"))
    default = replay.write_replay(tmp_path, cell.cell_id, 1, tmp_path / "d.gif")
    assert np.array_equal(_frames(default), _frames(tmp_path / "argmax.gif"))
    with pytest.raises(BenchError, match="'sample@0.25': cell .* was evaluated in argmax, sample, sample@0.5"):
        replay.write_replay(tmp_path, cell.cell_id, 1, tmp_path / "x.gif", execution="sample@0.25")
    with pytest.raises(BenchError, match="unknown execution mode 'argmx'"):
        replay.write_replay(tmp_path, cell.cell_id, 1, tmp_path / "x.gif", execution="argmx")
# ------------------------------------------------------------- readable frames (issue #16)
def _recorder_on(layout_name: str, n: int = 8, z: int = 4, steps: int = 2, proposals: bool = True,
                 links: bool = True) -> tuple[object, replay.Recorder, np.ndarray, np.ndarray]:
    """A hand-made recording on a layout: robots on the first free cells, goals on the last."""
    from envs.layouts import load_layout

    layout = load_layout(layout_name)
    adjacency = ~np.eye(z, dtype=bool)
    rec = replay.Recorder(0, adjacency, has_proposals=proposals)
    rec.goal = np.arange(len(layout.cells) - n, len(layout.cells))
    for t in range(steps):
        lost = np.zeros((z, z), bool)
        lost[0, 1] = True
        rec.steps.append(replay.Step(t, np.arange(n) + t, np.zeros(n, bool), np.ones(n, bool),
                                     np.eye(1, n, 0, dtype=bool)[0], np.eye(1, n, 1, dtype=bool)[0],
                                     (adjacency & ~lost) if links and t else None))
    return layout, rec, np.arange(n) % z, adjacency


def test_render_steps__movingai_frames_are_at_least_800_px_wide_with_the_legend_at_the_bottom():
    from reports.figures.replay_frames import LegendSpec, legend_panel

    layout, rec, groups, adj = _recorder_on("warehouse-10-20-10-2-1")
    frames = replay.render_steps(layout, rec, groups, adj, 60, "title")
    assert frames[0].shape[1] >= 800 and frames[0].shape[0] >= 63 * 6
    legend = legend_panel(frames[0].shape[1], LegendSpec(groups=4, links=True, corrections=True))
    np.testing.assert_array_equal(frames[1][-legend.shape[0]:], legend)
    tiny = replay.render_steps(*_recorder_on("tiny")[0:2], groups, adj, 60, "title")
    assert tiny[0].shape[1] >= 800


def test_legend__names_every_mark_the_frames_can_show():
    from reports.figures.replay_frames import LegendSpec, legend_items

    full = [label for _, label in legend_items(LegendSpec(3, links=True, corrections=True), 12)]
    assert full[:3] == ["group 0", "group 1", "group 2"]
    for needle in ("goal", "finished", "collision", "safety filter", "inter-group links", "lost", "not an edge"):
        assert any(needle in label for label in full), needle
    plain = [label for _, label in legend_items(LegendSpec(3, links=False, corrections=False), 12)]
    assert not any("safety filter" in label or "lost" in label for label in plain)


def test_font__is_matplotlibs_dejavu_truetype():
    from PIL import ImageFont

    from reports.figures.replay_frames import font

    f = font(15)
    assert isinstance(f, ImageFont.FreeTypeFont) and "DejaVuSans" in f.path


def test_write_replay__caption_names_method_n_p_cell_episode_and_execution(tmp_path, monkeypatch):
    cell, rows = _store(tmp_path)
    captions = []
    compose = replay.compose

    def spy(caption, *args, **kwargs):
        captions.append([text for text, _ in caption])
        return compose(caption, *args, **kwargs)

    monkeypatch.setattr(replay, "compose", spy)
    replay.write_replay(tmp_path, cell.cell_id, 3, tmp_path / "r.gif")
    title = captions[0][0]
    for needle in ("PIBT", "N=6", "p=0.5", "Z=3", "tiny", f"cell {cell.cell_id}", "episode 3",
                   "execution planner"):
        assert needle in title, (needle, title)
    assert captions[-1][1].startswith(f"t = {rows[3]['steps']}/40")
    assert len(captions) == rows[3]["steps"] + 1


def test_write_replay__reports_progress_of_every_phase(tmp_path, capsys):
    cell, rows = _store(tmp_path)
    calls = []
    replay.write_replay(tmp_path, cell.cell_id, 3, tmp_path / "r.gif", progress=lambda *a: calls.append(a))
    phases = [c[0] for c in calls]
    assert phases[0] == "re-running the episode" and phases[-1] == "encoding gif"
    frames = [c for c in calls if c[0] == "drawing frames"]
    assert frames[-1][1:] == (rows[3]["steps"] + 1,) * 2 and [c[1] for c in frames] == list(range(1, len(frames) + 1))
    with replay.replay_progress() as progress:  # not a terminal: plain lines on stderr
        for i in range(9):
            progress("drawing frames", i, 8)
    err = capsys.readouterr().err.splitlines()
    assert err == [f"replay: drawing frames {i}/8" for i in (0, 2, 4, 6, 8)]


def test_write_replay__mp4_without_imageio_ffmpeg_is_one_clear_error(tmp_path, monkeypatch):
    cell, _ = _store(tmp_path)
    monkeypatch.setitem(__import__("sys").modules, "imageio_ffmpeg", None)  # import fails
    calls = []
    with pytest.raises(BenchError, match="--format mp4 needs the imageio-ffmpeg package.*use --format gif"):
        replay.write_replay(tmp_path, cell.cell_id, 3, tmp_path / "r.mp4", fmt="mp4",
                            progress=lambda *a: calls.append(a))
    assert calls == []  # refused before re-running the episode
    assert not list(tmp_path.glob("*.mp4")) and not list(tmp_path.glob(".*tmp*"))
    with pytest.raises(BenchError, match="unknown replay format 'avi'"):
        replay.write_replay(tmp_path, cell.cell_id, 3, tmp_path / "r.avi", fmt="avi")


def test_write_replay__mp4_has_one_frame_per_step(tmp_path):
    ffmpeg = pytest.importorskip("imageio_ffmpeg", reason="optional: MP4 output needs imageio-ffmpeg")
    cell, rows = _store(tmp_path)
    out = replay.write_replay(tmp_path, cell.cell_id, 3, tmp_path / "r.mp4", fmt="mp4")
    reader = ffmpeg.read_frames(str(out))
    meta = next(reader)
    assert meta["size"][0] >= 800 and meta["size"][0] % 16 == 0
    assert sum(1 for _ in reader) == rows[3]["steps"] + 1


def test_cli_replay__progress_on_stderr_and_mp4_error_is_one_line(tmp_path, capsys, monkeypatch):
    from bench.cli import main
    from bench.store.schema import SCHEMA_VERSION

    cell, _ = _store(tmp_path)
    RunStore(tmp_path).write_manifest({"schema_version": SCHEMA_VERSION})
    with pytest.raises(SystemExit) as exc:
        main(["replay", "--run", str(tmp_path), "--cell", cell.cell_id, "--episode", "1"])
    out = capsys.readouterr()
    assert exc.value.code in (0, None), out.err
    assert out.out.strip().endswith(f"{cell.cell_id}-ep1.gif")
    assert "replay: drawing frames" in out.err and "replay: encoding gif 1/1" in out.err
    monkeypatch.setitem(__import__("sys").modules, "imageio_ffmpeg", None)
    with pytest.raises(SystemExit) as exc:
        main(["replay", "--run", str(tmp_path), "--cell", cell.cell_id, "--format", "mp4"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1 and "pip install imageio-ffmpeg" in err
