"""make cluster-check: the README's Ray cluster recipe (docs/deployment.md) on three test hosts.

    sudo .venv/bin/python scripts/cluster_check.py [--reference results/ci-smoke]

Makes network namespaces of its own: a bridge in one, and a head and two worker hosts on
10.231.0.0/24, each joined to the bridge by a veth pair, with loopback and no other route.
Runs the recipe block of docs/deployment.md line by line (``# [role]`` tags say where;
HEAD_IP and NODE_IP replaced), each host with its own HOME and Ray temp dir, the driver's
``bench run --address`` in the head's namespace; once the run has stored training rows it
kills every process in the second worker's namespace. Checks: the run finishes with every
cell done and some retried, its rows equal a single-machine run of the same grid bit for bit
(``--reference``, else one is made), the token files are 0600, and ``ss -ltnp`` in every
namespace shows only the ports the recipe names. Cleans up (processes killed, namespaces
deleted) also on failure or Ctrl-C. Never runs ``ray stop``: that would stop every Ray
instance on the machine, not just the test's. Exit 0 passed, 1 failed, 2 cannot run here.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "deployment.md"
MARK = "<!-- cluster-recipe -->"
SUBNET = "10.231.0"
HOSTS = (("head", 11), ("w1", 12), ("w2", 13))
VICTIM = "w2"


def recipe(doc: Path = DOC) -> dict[str, list[str]]:
    """The recipe's command lines by role (all, token, head, worker, driver, stop)."""
    text = doc.read_text()
    if MARK not in text:
        raise SystemExit(f"cluster_check: no {MARK} block in {doc}")
    block = text.split(MARK, 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    roles: dict[str, list[str]] = {}
    role = ""
    for line in block.strip().splitlines():
        tag = re.match(r"#\s*\[(\w+)\]", line)
        if tag:
            role = tag.group(1)
        elif line.strip() and not line.startswith("#"):
            roles.setdefault(role, []).append(line.strip())
    return roles


RAY_CLIENT_PORT = 10001  # `ray start --head` opens it when grpcio for Ray's client is installed


def documented_ports(lines: list[str]) -> set[int]:
    """Every port a set of `ray start` lines names: fixed ports and the worker port range."""
    ports = {int(p) for line in lines for p in re.findall(r"-port=(\d+)", line)}
    for line in lines:
        lo, hi = re.search(r"--min-worker-port=(\d+)", line), re.search(r"--max-worker-port=(\d+)", line)
        if lo and hi:
            ports |= set(range(int(lo.group(1)), int(hi.group(1)) + 1))
    return ports


@dataclass
class Host:
    name: str
    ns: str
    ip: str
    home: Path
    env: dict[str, str] = field(default_factory=dict)

    def sh(self, script: str, **kw) -> subprocess.Popen:
        """`bash -c script` inside this host's namespace, in the repository, with its env."""
        return subprocess.Popen(["ip", "netns", "exec", self.ns, "bash", "-c", script],
                                cwd=REPO, env=self.env, **kw)

    def run(self, script: str, timeout: float = 120) -> str:
        p = self.sh(script, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        out, _ = p.communicate(timeout=timeout)
        if p.returncode:
            raise RuntimeError(f"{self.name}: `{script}` exited {p.returncode}:\n{out[-3000:]}")
        return out


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, text=True)


def _kill_namespace(ns: str) -> None:
    """SIGKILL every process in namespace ns (only ours: the namespace is this check's)."""
    for _ in range(20):
        out = subprocess.run(["ip", "netns", "pids", ns], capture_output=True, text=True).stdout.split()
        if not out:
            return
        for pid in out:
            try:
                os.kill(int(pid), signal.SIGKILL)
            except ProcessLookupError:
                pass
        time.sleep(0.3)


@contextmanager
def netns_hosts(root: Path, env: dict[str, str]) -> Iterator[dict[str, Host]]:
    """Three hosts in their own network namespaces on a bridge in a fourth; removed afterwards."""
    tag = f"wmbc{os.getpid() % 100000}"
    bridge = f"{tag}-br"
    made: list[str] = []
    hosts: dict[str, Host] = {}
    try:
        _ip("netns", "add", bridge)
        made.append(bridge)
        _ip("-n", bridge, "link", "add", "br0", "type", "bridge")
        _ip("-n", bridge, "link", "set", "br0", "up")
        for name, octet in HOSTS:
            ns = f"{tag}-{name}"
            _ip("netns", "add", ns)
            made.append(ns)
            _ip("-n", ns, "link", "add", "eth0", "type", "veth", "peer", "name", f"v{name}", "netns", bridge)
            _ip("-n", bridge, "link", "set", f"v{name}", "master", "br0", "up")
            _ip("-n", ns, "addr", "add", f"{SUBNET}.{octet}/24", "dev", "eth0")
            _ip("-n", ns, "link", "set", "eth0", "up")
            _ip("-n", ns, "link", "set", "lo", "up")
            home = root / name
            (home / "tmp").mkdir(parents=True)
            hosts[name] = Host(name, ns, f"{SUBNET}.{octet}", home, {
                **env, "HOME": str(home), "RAY_TMPDIR": str(home / "tmp"), "TMPDIR": str(home / "tmp"),
                "RAY_USAGE_STATS_ENABLED": "0"})
        yield hosts
    finally:
        for ns in reversed(made):
            _kill_namespace(ns)
            subprocess.run(["ip", "netns", "delete", ns], capture_output=True)


def listeners(host: Host) -> list[tuple[str, int, str]]:
    """(address, port, process) of every TCP listener in the host's namespace."""
    out = subprocess.run(["ip", "netns", "exec", host.ns, "ss", "-ltnpH"],
                         capture_output=True, text=True, check=True).stdout
    rows = []
    for line in out.splitlines():
        parts = line.split()
        addr, _, port = parts[3].rpartition(":")
        proc = re.search(r'\(\("([^"]+)"', line)
        rows.append((addr, int(port), proc.group(1) if proc else "?"))
    return sorted(rows, key=lambda r: r[1])


def _load_compare() -> ModuleType:
    path = REPO / "scripts" / "compare_runs.py"
    spec = importlib.util.spec_from_file_location("compare_runs", path)
    if spec is None or spec.loader is None:
        raise RuntimeError(f"cluster-check: cannot load {path}")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _option(command: str, flag: str) -> str:
    """The value of ``flag`` in the recipe's ``command`` line."""
    found = re.search(rf"{flag} (\S+)", command)
    if found is None:
        raise RuntimeError(f"cluster-check: the recipe's driver command has no {flag}: {command}")
    return found.group(1)


def check(reference: Path | None, keep_going_s: float = 600) -> int:
    roles = recipe()
    driver = roles["driver"][0]
    out_dir = REPO / _option(driver, "--out")
    grid = _option(driver, "--grid")
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_")}
    env["CI"] = "true"
    started = time.monotonic()
    if reference is None:
        reference = REPO / "results" / f"{grid}-cluster-reference"
        shutil.rmtree(reference, ignore_errors=True)
        subprocess.run([str(REPO / ".venv/bin/bench"), "run", "--grid", grid, "--out", str(reference)],
                       cwd=REPO, env=env, check=True, capture_output=True)
        print(f"cluster-check: single-machine reference {reference} ({time.monotonic() - started:.0f} s)")
    shutil.rmtree(out_dir, ignore_errors=True)
    with tempfile.TemporaryDirectory(prefix="wmbc-") as tmp, netns_hosts(Path(tmp), env) as hosts:
        head = hosts["head"]
        prelude = "set -e; " + "; ".join(roles["all"]) + "; "
        sub = lambda line, h: line.replace("HEAD_IP", head.ip).replace("NODE_IP", h.ip)  # noqa: E731
        head.run(prelude + "; ".join(roles["token"]))
        token = head.home / ".ray" / "auth_token"
        for h in hosts.values():  # "copy ~/.ray/auth_token (mode 0600) to every node and the driver"
            if h is not head:
                (h.home / ".ray").mkdir(mode=0o700)
                shutil.copy2(token, h.home / ".ray" / "auth_token")
            mode = (h.home / ".ray" / "auth_token").stat().st_mode & 0o777
            assert mode == 0o600, f"{h.name}: token file mode {oct(mode)}, not 0600"
        head.run(prelude + "; ".join(sub(x, head) for x in roles["head"]), timeout=180)
        for name in ("w1", "w2"):
            hosts[name].run(prelude + "; ".join(sub(x, hosts[name]) for x in roles["worker"]), timeout=180)
        print(f"cluster-check: head {head.ip} and workers {hosts['w1'].ip}, {hosts['w2'].ip} started "
              f"({time.monotonic() - started:.0f} s)")
        log = open(Path(tmp) / "driver.log", "w")
        drv = head.sh(prelude + sub(driver, head), stdout=log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + keep_going_s
        while time.monotonic() < deadline and drv.poll() is None:
            parts = list((out_dir / "train").rglob("*.parquet")) if (out_dir / "train").is_dir() else []
            if len(parts) >= 1 and any("ray::" in c for c in _cmdlines(hosts[VICTIM].ns)):
                break
            time.sleep(0.5)
        if drv.poll() is not None:
            print(open(Path(tmp) / "driver.log").read()[-3000:])
            print("cluster-check: FAILED: the run ended before the worker host could be killed")
            return 1
        table = {name: listeners(h) for name, h in hosts.items()}
        _kill_namespace(hosts[VICTIM].ns)
        print(f"cluster-check: killed every process of host {VICTIM} ({hosts[VICTIM].ip}) mid-run "
              f"({time.monotonic() - started:.0f} s)")
        rc: int | str
        try:
            rc = drv.wait(timeout=max(1.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            drv.kill()
            rc = "timeout"
        log.close()
        failures = []
        if rc != 0:
            failures.append(f"the driver exited {rc}:\n" + open(Path(tmp) / "driver.log").read()[-3000:])
        print("cluster-check: listeners (ss -ltnp in each namespace, just before the kill)")
        print("| host | address | port | process |\n|---|---|---|---|")
        for name, rows in table.items():
            allowed = documented_ports(roles["head" if name == "head" else "worker"])
            if name == "head":  # Ray's client server on its default port, documented in docs/deployment.md
                allowed.add(RAY_CLIENT_PORT)
            for addr, port, proc in rows:
                print(f"| {name} | {addr} | {port} | {proc} |")
                if port not in allowed:
                    failures.append(f"{name}: listener {addr}:{port} ({proc}) is not in the recipe")
        if rc == 0:
            import pandas as pd

            cells = pd.read_parquet(out_dir / "cells.parquet")
            if not (cells.status == "done").all():
                failures.append(f"cells not done: {cells[cells.status != 'done'].cell_id.tolist()}")
            retried = int((cells.attempts >= 2).sum())
            print(f"cluster-check: {len(cells)} cells done, {retried} retried after the kill")
            if not retried:
                failures.append("no cell was retried: the killed host ran no cell")
            equal, lines = _load_compare().compare(reference, out_dir, ("single machine", "cluster"))
            print("\n".join(f"cluster-check: {x}" for x in lines))
            if not equal:
                failures.append("cluster rows differ from the single-machine run")
    for f in failures:
        print(f"cluster-check: FAILED: {f}")
    print(f"cluster-check: {'passed' if not failures else 'failed'} in {time.monotonic() - started:.0f} s")
    return 1 if failures else 0


def _cmdlines(ns: str) -> list[str]:
    pids = subprocess.run(["ip", "netns", "pids", ns], capture_output=True, text=True).stdout.split()
    out = []
    for pid in pids:
        try:
            out.append(Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode())
        except OSError:
            pass
    return out


def can_run() -> str | None:
    """None when this machine can make network namespaces, else why not."""
    if os.geteuid() != 0:
        return "needs root (network namespaces)"
    if shutil.which("ip") is None or subprocess.run(["ip", "netns", "list"], capture_output=True).returncode:
        return "needs `ip netns` (iproute2)"
    return None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reference", type=Path, help="a single-machine run of the recipe's grid (else one is made)")
    args = ap.parse_args(argv)
    why = can_run()
    if why:
        print(f"cluster_check: {why}", file=sys.stderr)
        return 2
    if args.reference and not (args.reference / "cells.parquet").is_file():
        print(f"cluster_check: --reference {args.reference} is not a run folder (no cells.parquet)", file=sys.stderr)
        return 2
    return check(args.reference)


if __name__ == "__main__":
    sys.exit(main())
