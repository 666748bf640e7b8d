"""write_replay re-runs one evaluation episode from the store and checkpoint and records
it frame by frame (reports/replay.py). Runtime: about 3 s (PIBT on the tiny layout)."""
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
from bench.cells import Cell
from bench.schema import SCHEMA_VERSION
from bench.store import RunStore
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
        return Decision(actions=dec.actions, proposed=proposed, payload=dec.payload)


def test_recorder__links_and_corrections_are_those_of_the_episode(tmp_path, monkeypatch):
    monkeypatch.setattr(replay, "method_class",
                        lambda name: ChannelPIBT if name == "pibt" else method_class(name))
    cell, rows = _store(tmp_path, ChannelPIBT)
    k = 1  # episode 3 = chunk 1, slot 1
    env = cell.to_env_config()
    m = ChannelPIBT(env, cell.method_params().model_dump(mode="json"), seed=cell.seed)
    rec = replay.Recorder(k, ~np.eye(env.groups, dtype=bool))
    ChannelPIBT.drawn = []
    got = replay._run_recorded(m, 1, cell.seed, rec)
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
