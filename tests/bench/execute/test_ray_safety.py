"""Ray exposure and ends of a run (SPEC 7): the embedded Ray listens on loopback
only, the token file is private, a join refused for authentication says so, a lost head
node and SIGTERM each end with one line and a resumable store. The token tests are fast;
the rest start Ray (slow-marked; ~2 min together on 2 shared cores)."""
from __future__ import annotations

import os
import signal
import socket
import stat
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from bench.execute.ray_cluster import _is_auth_failure, secure_token_file
from bench.store.run_store import RunStore
from tests.bench.conftest import REPO, cli_argv, toy_spec, write_grid_file


@pytest.fixture
def token_home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("HOME", str(tmp_path))
    for var in ("RAY_AUTH_TOKEN", "RAY_AUTH_TOKEN_PATH", "RAY_AUTH_MODE"):
        monkeypatch.delenv(var, raising=False)
    return tmp_path / ".ray" / "auth_token"


def test_token_file__created_private_before_ray_would_create_it(token_home: Path) -> None:
    assert secure_token_file(create=True) == token_home
    assert stat.S_IMODE(token_home.stat().st_mode) == 0o600
    assert stat.S_IMODE(token_home.parent.stat().st_mode) == 0o700
    text = token_home.read_text()
    assert len(text) == 64 and int(text, 16) >= 0  # Ray's format: 256 bits as hex
    assert secure_token_file(create=True) == token_home and token_home.read_text() == text  # kept


def test_token_file__a_world_readable_one_is_made_private_unchanged(token_home: Path) -> None:
    token_home.parent.mkdir()
    token_home.write_text("ab" * 32)
    token_home.chmod(0o644)
    secure_token_file(create=False)
    assert stat.S_IMODE(token_home.stat().st_mode) == 0o600 and token_home.read_text() == "ab" * 32


def test_token_file__none_created_when_auth_is_disabled_or_the_token_is_in_the_environment(
        token_home: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")
    assert secure_token_file(create=True) is None and not token_home.exists()
    monkeypatch.delenv("RAY_AUTH_MODE")
    assert secure_token_file(create=False) is None and not token_home.exists()
    monkeypatch.setenv("RAY_AUTH_TOKEN", "cd" * 32)
    assert secure_token_file(create=True) is None and not token_home.exists()


def test_token_file__ray_auth_token_path_is_respected(token_home: Path, tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("RAY_AUTH_TOKEN_PATH", str(tmp_path / "shared" / "tok"))
    assert secure_token_file(create=True) == tmp_path / "shared" / "tok" and not token_home.exists()


@pytest.mark.parametrize(("text", "auth"), [
    ("gcs_client.cc:210: Failed to get cluster ID from GCS server: Unauthenticated: RPC error: "
     "InvalidAuthToken: Authentication token is missing or incorrect", True),
    ("AuthenticationError Token authentication is enabled but no authentication token was found", True),
    ("ConnectionError Failed to connect to Ray cluster at 10.0.0.1:6379", False),
    ("Token authentication is disabled for this Ray cluster.", False),
])
def test_auth_failure__is_recognized_from_rays_messages(text: str, auth: bool) -> None:
    assert _is_auth_failure(text) is auth


# ------------------------------------------------------------------- Ray
def _ray_pids(root: int) -> set[int]:
    """``root`` and every descendant process (Ray's GCS, raylet, agents, workers)."""
    children: dict[int, list[int]] = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(d.name))
    out, todo = set(), [root]
    while todo:
        pid = todo.pop()
        out.add(pid)
        todo += children.get(pid, [])
    return out


def _listeners(pids: set[int]) -> list[tuple[str, int, int]]:
    """(local address, port, pid) of the TCP sockets in LISTEN state owned by ``pids``
    (from /proc/net/tcp{,6} and /proc/<pid>/fd; the same as `ss -ltnp`)."""
    inodes: dict[str, int] = {}
    for pid in pids:
        try:
            for fd in Path(f"/proc/{pid}/fd").iterdir():
                link = os.readlink(fd)
                if link.startswith("socket:["):
                    inodes[link[8:-1]] = pid
        except OSError:
            continue
    out = []
    for table, family in (("tcp", socket.AF_INET), ("tcp6", socket.AF_INET6)):
        for line in Path(f"/proc/net/{table}").read_text().splitlines()[1:]:
            f = line.split()
            if f[3] != "0A" or f[9] not in inodes:  # 0A: LISTEN
                continue
            hexip, hexport = f[1].split(":")
            raw = bytes.fromhex(hexip)
            raw = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))  # per-word little endian
            out.append((socket.inet_ntop(family, raw), int(hexport, 16), inodes[f[9]]))
    return out


def _loopback(ip: str) -> bool:
    return ip.startswith("127.") or ip in ("::1", "::ffff:127.0.0.1") or ip.startswith("::ffff:127.")


EMBEDDED = """
import json, os, sys, time
sys.path.insert(0, {repo!r})
import ray
from bench.execute.ray_cluster import connect, CLUSTER_MODE_ENV
from tests.bench.execute.test_ray_safety import _listeners, _ray_pids
ctx = connect(None, 1)
@ray.remote
def ping():
    return 1
assert ray.get(ping.remote()) == 1  # a worker process is up and listening too
time.sleep(1.0)
found = _listeners(_ray_pids(os.getpid()))
env_left = os.environ.get(CLUSTER_MODE_ENV)
ctx.shutdown()
print(json.dumps({{"found": found, "env_left": env_left}}))
"""


@pytest.mark.slow
def test_embedded_ray__every_listener_is_on_loopback_and_the_token_is_private(tmp_path: Path) -> None:
    import json
    import sys

    env = {k: v for k, v in os.environ.items() if not k.startswith(("RAY_AUTH", "RAY_ADDRESS"))}
    env["HOME"] = str(tmp_path)  # its own token file; Ray caches the token per process, hence a subprocess
    proc = subprocess.run([sys.executable, "-c", EMBEDDED.format(repo=str(REPO))], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout.strip().splitlines()[-1])
    found = data["found"]
    assert len(found) >= 4, found  # GCS, raylet, driver and worker at least
    assert all(_loopback(ip) for ip, _, _ in found), found
    assert data["env_left"] is None  # cluster mode restored after start-up
    token = tmp_path / ".ray" / "auth_token"
    assert stat.S_IMODE(token.stat().st_mode) == 0o600 and len(token.read_text()) == 64


@pytest.fixture
def slow_grid(toy: str, tmp_path: Path) -> Path:
    base = toy_spec(episodes=24, eval_episodes=4, params={"sleep_s": 0.3})
    return write_grid_file(tmp_path / "g.toml", base, {"seed": [0, 1]})


def _wait_for_checkpoint(proc: subprocess.Popen, store: RunStore, timeout: float = 300) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        if store.ckpt_dir.is_dir() and any(store.ckpt_dir.glob("*.pt")):
            return
        time.sleep(0.1)
    out = proc.communicate(timeout=30)[1] if proc.poll() is not None else ""
    pytest.fail(f"no checkpoint before the run ended or timed out: {out}")


@pytest.fixture
def long_grid(toy: str, tmp_path: Path) -> Path:
    base = toy_spec(episodes=120, eval_episodes=4, params={"sleep_s": 0.3})  # ~18 s per cell
    return write_grid_file(tmp_path / "long.toml", base, {"seed": [0, 1]})


@pytest.mark.slow
def test_sigterm__ends_like_ctrl_c_with_exit_143_and_the_rerun_completes(slow_grid: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = cli_argv("run", "--grid-file", str(slow_grid), "--out", str(out), "--checkpoint-every", "1")
    env = {**os.environ, "CI": "true"}
    proc = subprocess.Popen(args, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        _wait_for_checkpoint(proc, RunStore(out))
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 143, err
    lines = [ln for ln in err.splitlines() if ln.startswith("bench:")]
    assert lines == ["bench: error: terminated; checkpoints are kept, rerun the same command to resume"], err
    assert "Traceback" not in err and "SIGTERM" not in err
    assert any(RunStore(out).ckpt_dir.glob("*.pt"))
    rerun = subprocess.run(args, cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    train = RunStore(out).read_train()
    assert sorted(train.groupby("cell_id").size().tolist()) == [24, 24]
    assert not train.duplicated(["cell_id", "episode"]).any()


HEAD = ("import sys; from ray.cluster_utils import Cluster; "
        "c = Cluster(initialize_head=True, head_node_args={'num_cpus': 1, 'include_dashboard': False}); "
        "print(c.address, flush=True); sys.stdin.read(); c.shutdown()")


@pytest.fixture
def token_cluster(tmp_path: Path) -> Iterator[tuple[str, Path]]:
    """A one-node cluster started with token authentication and its own token file, in its
    own process (Ray caches the token per process)."""
    import sys

    token = tmp_path / "cluster_token"
    token.write_text("ef" * 32)
    token.chmod(0o600)
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN_PATH": str(token)}
    head = subprocess.Popen([sys.executable, "-c", HEAD], env=env, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        address = head.stdout.readline().strip()  # type: ignore[union-attr]
        assert address, "the head node did not start"
        yield address, token
    finally:
        head.stdin.close()  # type: ignore[union-attr]
        try:
            head.wait(timeout=60)
        except subprocess.TimeoutExpired:
            head.kill()
            head.wait()


@pytest.mark.slow
def test_address__a_join_refused_for_authentication_says_so_and_the_recipe_works(
        token_cluster: tuple[str, Path], tmp_path: Path) -> None:
    address, token = token_cluster
    grid = tmp_path / "g.toml"
    grid.write_text('[base]\nmethod = "pibt"\nlayout = "tiny"\nepisodes = 0\nhorizon = 20\n'
                    'eval_episodes = 4\n[axes]\nn_robots = [4]\nloss_p = [0.2]\n')
    args = ["run", "--grid-file", str(grid), "--out", str(tmp_path / "run"), "--address", address]
    base = {k: v for k, v in os.environ.items() if not k.startswith("RAY_AUTH")}
    base.update(CI="true", HOME=str(tmp_path))  # no ~/.ray/auth_token of the user either
    refused = subprocess.run(cli_argv(*args), cwd=REPO, env=base, capture_output=True, text=True, timeout=240)
    assert refused.returncode == 2, refused.stderr
    assert refused.stderr.count("\n") == 1 and "authentication failed" in refused.stderr, refused.stderr
    assert "RAY_AUTH_MODE=token" in refused.stderr and not (tmp_path / "run").exists()
    # README recipe: share the head's token and turn token mode on in the driver
    ok = subprocess.run(cli_argv(*args), cwd=REPO, capture_output=True, text=True, timeout=240,
                        env={**base, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN_PATH": str(token)})
    assert ok.returncode == 0, ok.stderr
    assert (RunStore(tmp_path / "run").read_cells()["status"] == "done").all()


@pytest.mark.slow
def test_address__a_head_node_that_dies_mid_run_is_one_line(long_grid: Path, tmp_path: Path) -> None:
    """The head's GCS dies while the driver's own raylet lives on (a driver on another node):
    one line after ~8 s instead of Ray's 60 s wait and C++ crash log."""
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 2, "include_dashboard": False})
    gcs = cluster.head_node.all_processes["gcs_server"][0].process
    out = tmp_path / "run"
    proc = subprocess.Popen(cli_argv("run", "--grid-file", str(long_grid), "--out", str(out), "--address",
                                     cluster.address, "--checkpoint-every", "1"),
                            cwd=REPO, env={**os.environ, "CI": "true"}, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        _wait_for_checkpoint(proc, RunStore(out))
        gcs.kill()
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        cluster.shutdown()
    assert proc.returncode == 2, err
    lines = [ln for ln in err.splitlines() if ln.startswith("bench:")]
    assert len(lines) == 1 and "lost the Ray cluster" in lines[0] and "rerun to resume" in lines[0], err
    assert any(RunStore(out).ckpt_dir.glob("*.pt"))
