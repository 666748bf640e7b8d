"""Starting or joining Ray for a bench run (SPEC 4 "Execution on Ray", SPEC 7 "Ray").

* Embedded (default): ``ray.init`` on this machine with as many CPUs as it has (or as
  ``--workers`` asks), no dashboard, a small object store (checkpoint states and rows
  are small), worker logs not forwarded to the driver, node address 127.0.0.1.
* ``--address host:port`` or ``RAY_ADDRESS``: join an existing cluster. Ray 2.59+
  clusters use token authentication: start the cluster with ``RAY_AUTH_MODE=token`` and
  give the driver the same token (``RAY_AUTH_TOKEN`` or ``~/.ray/auth_token``). An
  unreachable address is a BenchError (exit 2) after a short TCP probe, not a long hang.
* An already initialized Ray (tests, notebooks) is used as is and left running.
"""
from __future__ import annotations

import logging
import os
import socket
from dataclasses import dataclass

from envs.errors import BenchError

OBJECT_STORE_BYTES = 150 * 1024**2  # states and rows only: enough, and fits a 2-core CI box
PROBE_TIMEOUT_S = 3.0


@dataclass
class RayContext:
    started_here: bool
    address: str
    cpus: int

    def shutdown(self) -> None:
        if self.started_here:
            import ray

            ray.shutdown()


def local_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


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
    """Start embedded Ray or join ``address`` (or RAY_ADDRESS); BenchError when unreachable."""
    import ray

    if ray.is_initialized():
        return RayContext(False, "existing", _cluster_cpus())
    address = address or os.environ.get("RAY_ADDRESS") or None
    quiet = dict(log_to_driver=False, logging_level=logging.ERROR)
    if address:
        if address != "auto":
            _probe(address)
        try:
            ray.init(address=address, **quiet)
        except Exception as exc:  # ConnectionError, auth failures, version mismatch
            msg = " ".join(str(exc).split())[:300]
            raise BenchError(f"cannot join Ray cluster at {address!r}: {msg}") from None
        return RayContext(True, address, _cluster_cpus())
    cpus = max(local_cores(), workers or 1)
    # address="local": always a new instance, never a cluster found in /tmp/ray by chance.
    ray.init(address="local", num_cpus=cpus, object_store_memory=OBJECT_STORE_BYTES,
             include_dashboard=False, _node_ip_address="127.0.0.1", **quiet)
    return RayContext(True, "embedded", cpus)


def _cluster_cpus() -> int:
    import ray

    return max(1, int(ray.cluster_resources().get("CPU", 1)))
