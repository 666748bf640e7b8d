"""SIGTERM stops every command like `bench run` (D5/D10): one line, exit 143, no
temp file left. One subprocess runs the CLI four times; each command sends itself SIGTERM
at a fixed point (no timing): in the middle of an atomic write of the report, and in the
body of tune, matrix and replay. On 738e05e the process died of the signal (or, after
ray.init, with Ray's crash dump and exit 134)."""
from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.bench.conftest import REPO, TOY_PATH

SCRIPT = '''
import io, json, os, signal, sys
from contextlib import redirect_stderr
from pathlib import Path
from algorithms import registry
registry.register("toy", {toy!r})
import bench.execute.signals
from bench.cli import main
import envs.atomic as atomic, reports.build as build, studies.cli as tune_cli
import bench.execute.matrix as matrix, reports.replay as replay

def stop(*a, **k):
    os.kill(os.getpid(), signal.SIGTERM)
    raise AssertionError("SIGTERM was not handled")

def save_figure(fig, stem, caption=""):  # the report is killed in the middle of its first write
    with atomic.atomic_path(stem.with_suffix(".png")) as tmp:
        Path(tmp).write_text("partial")
        stop()

build.save_figure = save_figure
tune_cli.tune_study = matrix.run_matrix = replay.write_replay = stop
out = {{}}
for name, args in json.loads(sys.argv[1]).items():
    bench.execute.signals._SIGTERM_RECEIVED[0] = False
    err = io.StringIO()
    with redirect_stderr(err):
        try:
            main(args)
            code = 0
        except SystemExit as exc:
            code = exc.code
    out[name] = [code, err.getvalue()]
print(json.dumps(out))
'''


def test_sigterm__report_tune_matrix_and_replay_exit_143_with_one_line_and_no_temp_file(
        one_cell_run: Path, tmp_path: Path) -> None:
    import pandas as pd

    cell = str(pd.read_parquet(one_cell_run / "cells.parquet")["cell_id"][0])
    cases = {"report": ["report", "--run", str(one_cell_run)],
             "tune": ["tune", "--study", "s", "--inline", "--out", str(tmp_path / "studies")],
             "matrix": ["matrix", "--run", str(one_cell_run)],
             "replay": ["replay", "--run", str(one_cell_run), "--cell", cell]}
    res = subprocess.run([sys.executable, "-c", SCRIPT.format(toy=TOY_PATH), json.dumps(cases)],
                         capture_output=True, text=True, cwd=REPO, timeout=300)
    assert res.returncode == 0, res.stderr[-3000:]
    results = json.loads(res.stdout.strip().splitlines()[-1])
    for name, (code, err) in results.items():
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert code == 143 and len(lines) == 1 and lines[0].startswith("bench: error: terminated"), (name, code, err)
    report = one_cell_run / "report"
    assert report.is_dir() and not [p for p in report.rglob("*") if p.name.startswith(".")]
    assert not (report / "fig1_training.png").exists()


def test_report__removes_temp_files_a_killed_report_left(tmp_path: Path) -> None:
    """SIGKILL leaves no chance to clean up: the next report removes them (build_report
    calls this first)."""
    from reports.build import remove_stale_temp_files

    stale = [tmp_path / ".summary.md.abc123.tmp", tmp_path / "studies" / "s" / ".study.html.x1y2.tmp"]
    for p in stale:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(b"")
    mine = tmp_path / ".mine.tmp"  # not a temp name of ours: kept
    mine.write_text("x")
    assert remove_stale_temp_files(tmp_path) == 2
    assert not any(p.exists() for p in stale) and mine.exists()


def test_connect__keeps_the_bench_sigterm_handler_over_ray_init(monkeypatch: pytest.MonkeyPatch) -> None:
    """ray.init installs a handler that dumps and exits 134; the bench's must stay."""
    import ray

    from bench.execute import ray_cluster
    from bench.execute.signals import sigterm_as_interrupt

    def fake_init(*a: object, **k: object) -> None:
        signal.signal(signal.SIGTERM, lambda *_: sys.exit(134))

    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "init", fake_init)
    with sigterm_as_interrupt():
        ours = signal.getsignal(signal.SIGTERM)
        ray_cluster.connect(None, 1)
        assert signal.getsignal(signal.SIGTERM) is ours
