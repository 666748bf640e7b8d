"""Where studies live and how a study is opened, resumed and repaired after a crash.

* Default: an embedded journal file on local disk, ``results/studies/<study>/journal.log``
  (Optuna's ``JournalStorage`` + ``JournalFileBackend``: append-only, safe for several
  writers on one file system, unlike SQLite under concurrent writes).
* ``--storage URL``: a shared RDB database (``postgresql://``, ``mysql://``, ``sqlite://``)
  for drivers on several machines; an unreachable or malformed URL is one ``BenchError``.
* The same study name resumes: the study keeps its settings, space and seed in its user
  attributes, and a rerun may only repeat them (a conflict is an error naming the field).
* Journal repair: appends are all-or-nothing (a full disk leaves whole records), and a torn
  record left by an interrupted write is dropped on open, saying so (studies/journal.py).
* Crash repair: each running trial carries a lease (driver host, pid, heartbeat). A
  RUNNING trial whose driver is gone (dead pid on this host, or no heartbeat for
  ``grace_s``) is marked FAIL and re-queued with the same parameters (``enqueue_trial``).
"""
from __future__ import annotations

import os
import re
import socket
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, Literal

import optuna
from optuna.storages import BaseStorage, JournalStorage, RDBStorage
from optuna.trial import FrozenTrial, TrialState

from envs.errors import BenchError
from studies import DEFAULT_ROOT
from studies.journal import SafeJournalFileBackend

JOURNAL_FILE = "journal.log"
CONFIG_ATTR = "config"  # study user attribute holding settings, space and seed
LEASE_HOST, LEASE_PID, LEASE_BEAT = "driver_host", "driver_pid", "heartbeat"
RETRY_OF = "retry_of"
Direction = Literal["minimize", "maximize"]  # an objective's direction, as optuna spells it
REPLICATE = "replicate"  # replicate index of the trial's point (studies/schedule.py)
GRACE_S = 600.0  # a remote driver silent this long is considered dead
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")


def study_dir(name: str, root: str | Path = DEFAULT_ROOT) -> Path:
    """``root/<name>``; the name must be a plain folder name."""
    if not _NAME.match(name):
        raise BenchError(f"study name {name!r}: use letters, digits, '.', '_' or '-' (at most 100)")
    return Path(root) / name


def open_storage(url: str | None, directory: Path,
                 log: Callable[[str], None] | None = None) -> BaseStorage:
    """The journal file under ``directory`` (created; a torn record of an interrupted write
    is repaired, and ``log`` told what was recovered: studies/journal.py) or the RDB
    database at ``url``."""
    if url is None:
        directory.mkdir(parents=True, exist_ok=True)
        backend = SafeJournalFileBackend(str(directory / JOURNAL_FILE))
        if backend.repaired:
            (log or _warn)(backend.repaired)
        try:
            return JournalStorage(backend)
        except (ValueError, KeyError, TypeError) as exc:  # a record Optuna cannot replay
            raise BenchError(f"study journal {str(directory / JOURNAL_FILE)!r} cannot be replayed: "
                             f"{' '.join(str(exc).split())[:200]}") from None
    shown = _redact(url)
    try:
        return RDBStorage(url, engine_kwargs=_engine_kwargs(url))
    except Exception as exc:  # sqlalchemy raises many types; the user needs one line
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise BenchError(f"cannot open study storage {shown}: {reason}") from None


def _warn(message: str) -> None:
    import sys

    print(f"bench: warning: {message}", file=sys.stderr)


def _engine_kwargs(url: str) -> dict[str, Any]:
    if url.startswith(("postgresql", "mysql")):
        return {"connect_args": {"connect_timeout": 10}, "pool_pre_ping": True}
    return {}


def _redact(url: str) -> str:
    try:
        from sqlalchemy.engine import make_url

        return make_url(url).render_as_string(hide_password=True)
    except Exception:
        return re.sub(r"//([^:/@]+):[^@]*@", r"//\1:***@", url)


def open_study(name: str, storage: BaseStorage, directions: list[Direction], seed: int,
               pruner: optuna.pruners.BasePruner) -> optuna.Study:
    """Create or load study ``name``; its sampler is a seeded TPE (constant liar, parallel),
    consulted only by TPE searches (an exhaustive search enqueues every trial's parameters).

    The sampler seed also depends on how many trials the study already holds, so a
    resumed study does not replay the random start-up proposals of its first run.
    """
    import warnings

    import numpy as np

    try:
        existing = optuna.study.get_all_study_names(storage)
    except Exception as exc:
        raise BenchError(f"cannot read study storage: {exc}") from None
    n_before = 0
    if name in existing:
        loaded = optuna.load_study(study_name=name, storage=storage)
        if [d.name.lower() for d in loaded.directions] != directions:
            raise BenchError(f"study {name!r} exists with {len(loaded.directions)} objective(s); "
                             f"rerun it with the same --objectives or pick a new --study name")
        n_before = len(loaded.get_trials(deepcopy=False))
    sampler_seed = int(np.random.SeedSequence([int(seed), 2, n_before]).generate_state(1)[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        sampler = optuna.samplers.TPESampler(seed=sampler_seed, constant_liar=True)
    return optuna.create_study(study_name=name, storage=storage, directions=directions,
                               sampler=sampler, pruner=pruner, load_if_exists=True)


def stored_config(storage: BaseStorage, name: str) -> dict[str, Any] | None:
    """The config an existing study was created with (None: no such study or none stored)."""
    if name not in optuna.study.get_all_study_names(storage):
        return None
    return dict(optuna.load_study(study_name=name, storage=storage).user_attrs.get(CONFIG_ATTR) or {})


def merge_config(name: str, stored: Mapping[str, Any] | None, given: Mapping[str, Any],
                 explicit: set[str]) -> dict[str, Any]:
    """The config to run: ``given`` for a new study; for a resumed one the stored config,
    and every key the user typed (``explicit``) must repeat the stored value."""
    if not stored:
        return dict(given)
    for key in sorted(explicit):
        if key in given and _norm(stored.get(key)) != _norm(given[key]):
            raise BenchError(
                f"study {name!r} was created with {key}={stored.get(key)!r}, not "
                f"{given[key]!r}; omit the option to resume it or pick a new --study name")
    return {**given, **stored}


def _norm(value: Any) -> Any:
    if isinstance(value, (list, tuple)):
        return [_norm(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _norm(v) for k, v in value.items()}
    return value


# ----------------------------------------------------------------------- leases
def lease_attrs() -> dict[str, Any]:
    """User attributes marking a trial as run by this driver, now."""
    return {LEASE_HOST: socket.gethostname(), LEASE_PID: os.getpid(), LEASE_BEAT: time.time()}


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def is_orphan(trial: FrozenTrial, grace_s: float = GRACE_S, now: float | None = None) -> bool:
    """A RUNNING trial whose driver is gone: no lease, a dead local pid, or a stale beat."""
    attrs = trial.user_attrs
    if LEASE_PID not in attrs or LEASE_BEAT not in attrs:
        return True
    now = time.time() if now is None else now
    if now - float(attrs[LEASE_BEAT]) > grace_s:
        return True
    if attrs.get(LEASE_HOST) == socket.gethostname():
        pid = int(attrs[LEASE_PID])
        return pid != os.getpid() and not _pid_alive(pid)
    return False


def requeue(study: optuna.Study, trial: FrozenTrial, reason: str) -> None:
    """Mark ``trial`` FAIL (if still running) and enqueue its parameters again.

    The new trial keeps ``retry_of`` = the first trial of the chain and its replicate
    index, which fixes its seed, so a re-run trial trains exactly what the crashed one
    would have.
    """
    root = int(trial.user_attrs.get(RETRY_OF, trial.number))
    attrs: dict[str, Any] = {RETRY_OF: root}
    if REPLICATE in trial.user_attrs:
        attrs[REPLICATE] = int(trial.user_attrs[REPLICATE])
    if trial.state == TrialState.RUNNING:
        study._storage.set_trial_user_attr(trial._trial_id, "error", reason)
        study.tell(trial.number, state=TrialState.FAIL, skip_if_finished=True)
    study.enqueue_trial(dict(trial.params), user_attrs=attrs, skip_if_exists=False)


def recover_orphans(study: optuna.Study, grace_s: float = GRACE_S) -> list[int]:
    """Fail and re-queue every orphaned RUNNING trial; returns their numbers."""
    out = []
    for trial in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        if is_orphan(trial, grace_s):
            requeue(study, trial, "driver crashed or was interrupted; re-queued")
            out.append(trial.number)
    return out
