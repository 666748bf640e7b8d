"""Starting or joining Ray for a bench run (SPEC 4 "Execution on Ray", SPEC 7 "Ray").

* Embedded (default): ``ray.init`` on this machine with as many CPUs as it has (or as
  ``--workers`` asks), no dashboard, a small object store (checkpoint states and rows
  are small), worker logs not forwarded to the driver, every listener on 127.0.0.1.
  Ray 2.60 turns ``_node_ip_address="127.0.0.1"`` into the machine's outward address
  (``resolve_ip_for_localhost``) and then binds its gRPC servers to 0.0.0.0; it keeps
  loopback only when its "cluster mode" is off (``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0``,
  the switch it uses on macOS/Windows), which ``_loopback_only`` sets while Ray starts
  (the GCS, raylet, agents and workers inherit it). ``ss -ltnp`` then shows 127.0.0.1 only.
* Token: Ray 2.60 enables token authentication for a new local cluster and writes
  ``~/.ray/auth_token`` with the umask's permissions (often world-readable). The bench
  creates the token itself with mode 0600 (same format: 64 hex digits) before Ray would,
  and tightens an existing one to 0600 (``secure_token_file``).
* ``--address host:port`` or ``RAY_ADDRESS``: join an existing cluster. A cluster started
  with token authentication (``RAY_AUTH_MODE=token``, or a plain ``ray start`` once a token
  file exists) needs the same token in the driver: ``~/.ray/auth_token``,
  ``RAY_AUTH_TOKEN_PATH`` or ``RAY_AUTH_TOKEN``, and ``RAY_AUTH_MODE=token`` (Ray sends a
  token to an explicit address only when told to; the bench keeps that rule). Ray's C++
  log lines of a failed join are captured; a failure whose cause is authentication
  (``InvalidAuthToken``/``Unauthenticated``) says so in one line. An unreachable address is
  a BenchError (exit 2) after a short TCP probe, not a long hang.
* An already initialized Ray (tests, notebooks) is used as is and left running.
"""
from __future__ import annotations

import logging
import os
import secrets
import socket
import stat
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from envs.errors import BenchError

OBJECT_STORE_BYTES = 150 * 1024**2  # states and rows only: enough, and fits a 2-core CI box
PROBE_TIMEOUT_S = 3.0
CLUSTER_MODE_ENV = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"  # ray._private.ray_constants
AUTH_MODE_ENV, TOKEN_ENV, TOKEN_PATH_ENV = "RAY_AUTH_MODE", "RAY_AUTH_TOKEN", "RAY_AUTH_TOKEN_PATH"
AUTH_HINT = ("Ray token authentication failed: give the driver the cluster's token "
             "(copy the head's ~/.ray/auth_token, or set RAY_AUTH_TOKEN_PATH or RAY_AUTH_TOKEN) and "
             "export RAY_AUTH_MODE=token; see README 'Running on a Ray cluster'")


HEAD_LOST_AFTER_S = 8.0  # the head's GCS port refusing connections this long: the cluster is gone
HEAD_PROBE_EVERY_S = 2.0


class ClusterLost(BenchError):
    """The head node of a joined cluster stopped answering during a run."""


@dataclass
class RayContext:
    started_here: bool
    address: str
    cpus: int
    gcs: str = ""  # host:port of a joined cluster's head (GCS), probed during the run
    lost: bool = False
    _failing_since: float = 0.0
    _next_probe: float = 0.0

    def check_head(self) -> None:
        """ClusterLost when the joined cluster's head has refused TCP connections for
        HEAD_LOST_AFTER_S (Ray itself would wait 60 s, then exit with a C++ crash log)."""
        import time

        now = time.monotonic()
        if not self.gcs or now < self._next_probe:
            return
        self._next_probe = now + HEAD_PROBE_EVERY_S
        host, _, port = self.gcs.rpartition(":")
        try:
            with socket.create_connection((host.strip("[]"), int(port)), timeout=PROBE_TIMEOUT_S):
                self._failing_since = 0.0
                return
        except OSError:
            self._failing_since = self._failing_since or now
        if now - self._failing_since >= HEAD_LOST_AFTER_S:
            self.lost = True
            raise ClusterLost(
                f"lost the Ray cluster at {self.address!r}: its head node ({self.gcs}) stopped "
                f"answering; finished cells and checkpoints are stored; rerun to resume"
            )

    def shutdown(self) -> None:
        if self.started_here and not self.lost:
            import ray

            ray.shutdown()


def local_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def token_path() -> Path:
    """Where Ray 2.60 reads the token file: RAY_AUTH_TOKEN_PATH, else ~/.ray/auth_token."""
    return Path(os.environ.get(TOKEN_PATH_ENV) or Path.home() / ".ray" / "auth_token")


def secure_token_file(create: bool) -> Path | None:
    """Make the Ray token file private (0600; its folder 0700 when the bench creates it).

    ``create``: write a new token (64 hex digits, like ``ray get-auth-token --generate``)
    when none exists and token auth is not disabled, so Ray never creates a world-readable
    one. An existing file of this user is chmod-ed to 0600. Returns the path, if any.
    """
    path = token_path()
    if os.environ.get(TOKEN_ENV):
        return None  # the token is in the environment; no file involved
    if not path.exists():
        if not create or os.environ.get(AUTH_MODE_ENV, "").lower() == "disabled":
            return None
        path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except FileExistsError:  # created meanwhile: fall through to the chmod below
            pass
        else:
            with os.fdopen(fd, "w") as fh:
                fh.write(secrets.token_hex(32))
    st = path.stat()
    if st.st_uid == os.getuid() and stat.S_IMODE(st.st_mode) & 0o077:
        os.chmod(path, 0o600)
    return path


class _StderrCapture:
    """Redirect file descriptor 2 (Ray's C++ logging writes there) to a temp file; ``text``
    holds what was written. Used around joining a cluster: a failed join becomes one line."""

    def __init__(self) -> None:
        self.text = ""

    def __enter__(self) -> _StderrCapture:
        import sys
        import tempfile

        sys.stderr.flush()
        self._tmp = tempfile.TemporaryFile()
        self._saved = os.dup(2)
        os.dup2(self._tmp.fileno(), 2)
        return self

    def __exit__(self, *exc: object) -> None:
        import sys

        sys.stderr.flush()
        os.dup2(self._saved, 2)
        os.close(self._saved)
        self._tmp.seek(0)
        self.text = self._tmp.read()[-20_000:].decode(errors="replace")
        self._tmp.close()


@contextmanager
def _loopback_only() -> Iterator[None]:
    """Ray's cluster mode off while an embedded instance starts: node IP and every
    listener on 127.0.0.1 (see the module docstring). Restored afterwards."""
    from ray._private import ray_constants

    old_env, old_flag = os.environ.get(CLUSTER_MODE_ENV), ray_constants.ENABLE_RAY_CLUSTER
    os.environ[CLUSTER_MODE_ENV] = "0"
    ray_constants.ENABLE_RAY_CLUSTER = False
    try:
        yield
    finally:
        ray_constants.ENABLE_RAY_CLUSTER = old_flag
        if old_env is None:
            os.environ.pop(CLUSTER_MODE_ENV, None)
        else:
            os.environ[CLUSTER_MODE_ENV] = old_env


def _is_auth_failure(text: str) -> bool:
    low = text.lower()
    return any(k in low for k in ("invalidauthtoken", "unauthenticated", "authenticationerror",
                                  "authentication token"))


def _probe(address: str) -> None:
    """TCP-connect to host:port of ``address`` (ray:// prefix allowed); BenchError if down."""
    target = address.removeprefix("ray://")
    host, sep, port = target.rpartition(":")
    if not sep or not port.isdigit() or not host:
        raise BenchError(f"--address {address!r}: expected host:port (or 'auto', or ray://host:port)")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=PROBE_TIMEOUT_S):
            pass
    except OSError as exc:
        raise BenchError(f"cannot reach Ray cluster at {address!r}: {exc.strerror or exc}") from None


def connect(address: str | None = None, workers: int | None = None) -> RayContext:
    """Start embedded Ray or join ``address`` (or RAY_ADDRESS); BenchError when unreachable.

    ``ray.init`` installs its own SIGTERM handler (a crash dump, exit 134); the bench's
    (bench/execute/signals.py ``sigterm_as_interrupt``: one line, exit 143), when active, is put back."""
    import signal

    try:
        old = signal.getsignal(signal.SIGTERM)
    except ValueError:  # pragma: no cover - not the main thread
        old = None
    try:
        with _keep_sigterm_handler(getattr(old, "bench_stop", False)):
            return _connect(address, workers)
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM while Ray started: leave no half-started node
        import ray

        with suppress(Exception):
            ray.shutdown()
        raise
    finally:
        if getattr(old, "bench_stop", False):
            signal.signal(signal.SIGTERM, old)


@contextmanager
def _keep_sigterm_handler(keep: bool) -> Iterator[None]:
    """While ``keep``, ``ray.init`` installs no SIGTERM handler of its own: a SIGTERM during
    start-up reaches the bench's (exit 143 and one line) instead of Ray's ``sys.exit(15)``,
    which ended the command silently. Ray sets its handlers through this one function."""
    if not keep:
        yield
        return
    from ray._private import utils

    original = utils.set_sigterm_handler
    utils.set_sigterm_handler = lambda handler: None
    try:
        yield
    finally:
        utils.set_sigterm_handler = original


def _connect(address: str | None, workers: int | None) -> RayContext:
    import ray

    if ray.is_initialized():
        return RayContext(False, "existing", _cluster_cpus())
    address = address or os.environ.get("RAY_ADDRESS") or None
    quiet: dict[str, Any] = dict(log_to_driver=False, logging_level=logging.ERROR)
    if address:
        if address != "auto":
            _probe(address)
        secure_token_file(create=False)
        log = _StderrCapture()
        try:
            with log:
                ray.init(address=address, **quiet)
        except Exception as exc:  # ConnectionError, auth failures, version mismatch
            msg = " ".join(str(exc).split())[:300]
            if _is_auth_failure(f"{type(exc).__name__} {msg} {log.text}"):
                mode = os.environ.get(AUTH_MODE_ENV, "unset")
                raise BenchError(f"cannot join Ray cluster at {address!r}: {AUTH_HINT} "
                                 f"(here RAY_AUTH_MODE is {mode})") from None
            raise BenchError(f"cannot join Ray cluster at {address!r}: {msg}") from None
        return RayContext(True, address, _cluster_cpus(), gcs=str(ray.get_runtime_context().gcs_address))
    cpus = max(local_cores(), workers or 1)
    secure_token_file(create=True)
    # address="local": always a new instance, never a cluster found in /tmp/ray by chance.
    try:
        with _loopback_only():
            ray.init(address="local", num_cpus=cpus, object_store_memory=OBJECT_STORE_BYTES,
                     include_dashboard=False, _node_ip_address="127.0.0.1", **quiet)
    except Exception as exc:  # e.g. the node's start-up timing out on a loaded machine (D19)
        with suppress(Exception):
            ray.shutdown()
        raise BenchError(f"could not start Ray on this machine ({type(exc).__name__}: "
                         f"{' '.join(str(exc).split())[:200]}); rerun the same command (a busy machine starts Ray "
                         "slower: try again when it is less loaded)") from None
    return RayContext(True, "embedded", cpus)


def _cluster_cpus() -> int:
    import ray

    return max(1, int(ray.cluster_resources().get("CPU", 1)))
