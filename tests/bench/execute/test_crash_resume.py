"""`bench run` killed with SIGKILL midway, then started again: every cell completes with
no duplicate and no missing row. Runtime: ~35 s on 2 shared cores (two Ray start-ups)."""
from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from bench.store.run_store import RunStore
from tests.bench.conftest import REPO, cli_argv, toy_spec, write_grid_file

EPISODES, EVAL = 16, 5


def _kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)  # the driver and the Ray processes it started
    except ProcessLookupError:
        pass
    proc.wait(timeout=30)


@pytest.mark.slow
def test_run__sigkill_midway_then_rerun_completes_without_duplicates_or_gaps(tmp_path: Path) -> None:
    base = toy_spec(episodes=EPISODES, eval_episodes=EVAL, params={"sleep_s": 0.15})
    grid_file = write_grid_file(tmp_path / "g.toml", base, {"seed": [0, 1], "n_robots": [4, 6]})
    out = tmp_path / "run"
    args = cli_argv("run", "--grid-file", str(grid_file), "--out", str(out), "--workers", "2",
                    "--checkpoint-every", "1")
    env = {**os.environ, "CI": "true"}
    store = RunStore(out)
    proc = subprocess.Popen(args, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 150
        while time.monotonic() < deadline and proc.poll() is None:
            evals = list(store.eval_dir.glob("*.parquet")) if store.eval_dir.exists() else []
            parts = list(store.train_dir.rglob("part-*.parquet")) if store.train_dir.exists() else []
            unfinished = {p.parent.name for p in parts} - {p.stem for p in evals}
            if evals and unfinished:  # some cells done, another one mid-training
                break
            time.sleep(0.05)
        assert proc.poll() is None, "the run ended before it could be killed:\n" + proc.stdout.read().decode()
        _kill_group(proc)
    finally:
        if proc.poll() is None:
            _kill_group(proc)
    cells = store.read_cells()
    assert (cells["status"] != "done").any(), "nothing left to resume"
    done_before = set(cells.loc[cells["status"] == "done", "cell_id"])

    rerun = subprocess.run(args, cwd=REPO, env=env, capture_output=True, text=True, timeout=240)
    assert rerun.returncode == 0, rerun.stdout + rerun.stderr
    cells = store.read_cells().set_index("cell_id")
    assert len(cells) == 4 and (cells["status"] == "done").all()
    train, evals = store.read_train(), store.read_eval()
    for cid in cells.index:
        assert sorted(train.loc[train.cell_id == cid, "episode"]) == list(range(EPISODES)), cid
        ev = evals[evals.cell_id == cid]
        for mode in ("argmax", "sample", "sample@0.5"):  # every mode, each episode once
            assert sorted(ev.loc[ev.execution == mode, "episode"]) == list(range(EVAL)), (cid, mode)
        assert len(ev) == 3 * EVAL, cid
    assert not any(p.name.endswith(".tmp") for p in out.rglob("*"))
    resumed = [cid for cid in cells.index if cid not in done_before]
    assert (cells.loc[resumed, "attempts"] >= 2).any(), "no cell was resumed from a checkpoint"
    assert (cells.loc[list(done_before), "attempts"] == 1).all()
