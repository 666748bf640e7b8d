"""The study journal survives a full disk and a torn write (D1): appends are
all-or-nothing, and a torn record (a cut last line, or a torn prefix glued to the next
record, as older versions left it) is dropped on open with one line saying what was kept."""
from __future__ import annotations

import errno
import json
from pathlib import Path

import optuna
import pytest

import studies.journal as journal_mod
from bench.cli import main
from envs.atomic import DiskFull
from studies.journal import SafeJournalFileBackend, repair_journal
from studies.storage import JOURNAL_FILE, open_storage

TINY = ["--method", "fake_hier", "--n-robots", "4", "--horizon", "16", "--episodes", "8",
        "--eval-episodes", "10", "--inline", "--workers", "1", "--param", "ref_size=2,32", "--param",
        "search_radius=1"]


def _bench(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as exc:
        main(args)
    out = capsys.readouterr()
    return int(exc.value.code or 0), out.out, out.err


def _journal_with_trials(directory: Path, n: int = 3) -> Path:
    storage = open_storage(None, directory)
    study = optuna.create_study(study_name="s", storage=storage)
    for i in range(n):
        study.enqueue_trial({"x": i})
        study.optimize(lambda t: t.suggest_int("x", 0, 10) * 1.0, n_trials=1)
    return directory / JOURNAL_FILE


def _complete(directory: Path, capsys: pytest.CaptureFixture[str] | None = None) -> list[float]:
    study = optuna.load_study(study_name="s", storage=open_storage(None, directory))
    return [t.value for t in study.get_trials(states=(optuna.trial.TrialState.COMPLETE,))]


def test_journal__a_torn_last_line_is_dropped_on_open_saying_what_was_kept(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _journal_with_trials(tmp_path / "s")
    whole = path.read_bytes()
    path.write_bytes(whole + b'{"op_code":5,"worker_id":"ab')  # a write cut short
    assert _complete(tmp_path / "s") == [0.0, 1.0, 2.0]
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "dropped the torn record" in err and "kept all" in err
    assert path.read_bytes() == whole
    assert [p.name for p in path.parent.glob("journal.log.torn-*")]  # the original is kept


def test_journal__a_torn_record_glued_to_the_next_one_is_recovered(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """What 738e05e left after a full disk and a rerun: every read failed with JSONDecodeError."""
    path = _journal_with_trials(tmp_path / "s", 2)
    lines = path.read_bytes().splitlines(keepends=True)
    glued = b"".join(lines[:-2]) + b'{"op_code":6,"trial_id":1,"sta' + b"".join(lines[-2:])
    path.write_bytes(glued)
    with pytest.raises(json.JSONDecodeError):  # Optuna alone cannot read it
        list(optuna.storages.journal.JournalFileBackend(str(path)).read_logs(0))
    assert _complete(tmp_path / "s") == [0.0, 1.0]
    assert "torn record" in capsys.readouterr().err


def test_journal__a_line_that_is_not_a_torn_write_is_refused_not_dropped(tmp_path: Path) -> None:
    path = _journal_with_trials(tmp_path / "s", 1)
    path.write_bytes(b"garbage\n" + path.read_bytes())
    from envs.errors import BenchError

    with pytest.raises(BenchError, match="line 1 is not a JSON record"):
        repair_journal(path)


def test_journal__a_full_disk_in_an_append_leaves_whole_records_and_names_the_journal(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = _journal_with_trials(tmp_path / "s", 1)
    before = path.read_bytes()
    backend = SafeJournalFileBackend(str(path))
    real_open = open

    class HalfFull:
        def __init__(self, fh):
            self.fh = fh

        def __enter__(self):
            return self

        def __exit__(self, *a):
            self.fh.close()

        def seek(self, *a):
            return self.fh.seek(*a)

        def truncate(self, n):
            return self.fh.truncate(n)

        def fileno(self):
            return self.fh.fileno()

        def flush(self):
            self.fh.flush()

        def write(self, data):
            self.fh.write(data[: len(data) // 2])
            self.fh.flush()
            raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(journal_mod, "open", lambda p, m: HalfFull(real_open(p, m)), raising=False)
    with pytest.raises(DiskFull, match="journal.log"):
        backend.append_logs([{"op_code": 0, "worker_id": "w", "study_name": "t", "directions": [1]}])
    assert path.read_bytes() == before


def test_tune__a_full_disk_then_a_rerun_resumes_with_every_finished_trial(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _bench(["tune", "--study", "d", "--trials", "2", "--out", str(tmp_path), *TINY], capsys)
    assert code == 0, err
    journal = tmp_path / "d" / JOURNAL_FILE
    done = json.loads(json.dumps(_finished(journal)))
    assert len(done) == 2
    real_open = open
    calls = {"n": 0}

    def filling(p, m):
        calls["n"] += 1
        fh = real_open(p, m)
        if calls["n"] > 3:  # the disk fills up a few records into the rerun
            orig = fh.write

            def write(data):
                orig(data[:7])
                fh.flush()
                raise OSError(errno.ENOSPC, "No space left on device")
            fh.write = write
        return fh

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(journal_mod, "open", filling, raising=False)
        code, _, err = _bench(["tune", "--study", "d", "--trials", "4", "--out", str(tmp_path), "--inline"], capsys)
    assert code == 2 and "disk full while writing" in err and "journal.log" in err, err
    assert sum(ln.startswith("bench: error:") for ln in err.splitlines()) == 1 and "Traceback" not in err, err
    assert all(json.loads(line) for line in journal.read_bytes().splitlines())  # whole records only
    code, out, err = _bench(["tune", "--study", "d", "--trials", "4", "--out", str(tmp_path), "--inline"], capsys)
    assert code == 0, err
    assert "4/4 finished trials" in out
    assert set(done) <= set(_finished(journal))  # every trial finished before the full disk is kept


def _finished(journal: Path) -> list[int]:
    study = optuna.load_study(study_name="d", storage=open_storage(None, journal.parent))
    return [t.number for t in study.get_trials() if t.state.is_finished() and t.state.name != "FAIL"]
