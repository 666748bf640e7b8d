"""Progress: ETA arithmetic, plain log lines on CI, rich only on a terminal."""
from __future__ import annotations

import io

import pytest

from bench.execute.progress import LogProgress, RichProgress, Snapshot, fmt_duration, make_progress


def test_snapshot__eta_extrapolates_the_cost_weighted_rate() -> None:
    snap = Snapshot(total=10, done=2, running=2, failed=1, fraction=0.25, elapsed_s=60.0)
    assert snap.eta_s == pytest.approx(180.0)
    assert Snapshot(10, 0, 0, 0, 0.0, 5.0).eta_s is None
    line = snap.line()
    assert "cells 2/10 done, 2 running, 1 failed" in line and "ETA 3m00s" in line


def test_fmt_duration__hours_minutes_seconds() -> None:
    assert [fmt_duration(s) for s in (5, 65, 3725)] == ["5s", "1m05s", "1h02m05s"]


def test_log_progress__prints_events_and_throttles_ticks() -> None:
    buf = io.StringIO()
    log = LogProgress(every_s=1e9, stream=buf)
    log.update(Snapshot(4, 0, 1, 0, 0.0, 1.0, message="started a"))
    log.update(Snapshot(4, 0, 1, 0, 0.1, 2.0))  # a tick without news: throttled
    log.update(Snapshot(4, 1, 0, 0, 0.3, 3.0, message="done a"))
    lines = buf.getvalue().splitlines()
    assert len(lines) == 2 and lines[0].endswith("| started a") and "cells 1/4 done" in lines[1]


def test_make_progress__plain_lines_on_ci_or_without_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CI", "true")
    assert isinstance(make_progress(), LogProgress)
    monkeypatch.delenv("CI")
    monkeypatch.setattr("sys.stderr", io.StringIO())  # not a TTY
    assert isinstance(make_progress(), LogProgress)
    monkeypatch.setattr("sys.stderr.isatty", lambda: True, raising=False)
    bar = make_progress()
    assert isinstance(bar, RichProgress)
    bar.update(Snapshot(2, 1, 1, 0, 0.5, 1.0, message="failed x"))
    bar.close()


def test_event_message__says_where_a_cell_is_and_is_not_repeated_by_later_events(tmp_path) -> None:
    """A resumed cell names its episode, a training chunk its progress, an evaluation unit
    its count; the runner prints each with its own event only (a checkpoint used to repeat
    the last 'started' line, which read as a restart)."""
    from bench.design.cells import Cell
    from bench.design.grids import Grid
    from bench.execute.plan import plan_run
    from bench.execute.runner import event_message
    from bench.store.run_store import RunStore

    grid = Grid("g", "test", (Cell.make(method="pibt", n_robots=4, loss_p=0.2, layout="tiny", episodes=0,
                                        horizon=10, eval_episodes=3, params={"eval_chunk": 2}),))
    st = plan_run(RunStore(tmp_path / "run"), grid, fresh=True)[0][0]
    label = st.label()
    assert event_message("started", st) == f"started {label}"
    st.episodes_done = 40
    assert event_message("started", st) == f"started {label} from episode 40"
    assert event_message("train_chunk", st) == f"trained {label}: 40/0 episodes, checkpoint written"
    st.trained = True
    assert event_message("started", st) == f"started {label}: evaluation"
    st.eval_rows[("planner", 0)] = []
    assert event_message("eval_chunk", st) == f"evaluated {label}: 1/2 units"
    st.error = "boom"
    assert event_message("failed", st) == f"failed {label}: boom"
    assert event_message("retry", st, "worker died " + "x" * 200) == f"retry {label} after worker died " + "x" * 68
    assert event_message("done", st) == f"done {label}"
    st.rerun = "was done but 1 of 3 evaluation rows stored; evaluating it again from its final checkpoint"
    assert event_message("rerun", st) == f"{label} {st.rerun}"
