"""scripts/cluster_check.py: the docs' cluster recipe on three network-namespace hosts.

The recipe parsing is checked everywhere (fast); the cluster itself (~4 min on 2 cores) runs
only under ``-m netns`` as root with ``ip netns`` (``make cluster-check``, which CI runs)."""
from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location(
    "cluster_check", Path(__file__).resolve().parents[2] / "scripts" / "cluster_check.py")
cc = importlib.util.module_from_spec(_spec)
sys.modules["cluster_check"] = cc  # its dataclass looks itself up there
_spec.loader.exec_module(cc)


def test_recipe__docs_block_has_every_role_the_check_runs() -> None:
    roles = cc.recipe()
    assert roles["all"] == ["export RAY_AUTH_MODE=token"]
    assert any("get-auth-token --generate" in x and "chmod 600" in x for x in roles["token"])
    assert roles["head"][0].startswith(".venv/bin/ray start --head --node-ip-address=HEAD_IP --port=6379")
    assert roles["worker"][0].startswith(".venv/bin/ray start --address=HEAD_IP:6379 --node-ip-address=NODE_IP")
    assert roles["driver"] == [".venv/bin/bench run --grid smoke --out results/smoke-cluster --address HEAD_IP:6379"]


def test_recipe__readme_shows_every_line_of_the_docs_recipe() -> None:
    readme = (cc.REPO / "README.md").read_text()
    roles = cc.recipe()
    for role in ("all", "token", "head", "worker", "driver", "stop"):
        for line in roles[role]:
            assert line in readme, f"README's cluster recipe lacks the docs' [{role}] line {line!r}"
    assert "docs/deployment.md" in readme


def test_documented_ports__fixed_ports_and_the_worker_range() -> None:
    ports = cc.documented_ports(["ray start --port=6379 --node-manager-port=6380 "
                                 "--min-worker-port=10002 --max-worker-port=10004"])
    assert ports == {6379, 6380, 10002, 10003, 10004}
    head, worker = cc.documented_ports(cc.recipe()["head"]), cc.documented_ports(cc.recipe()["worker"])
    assert 6379 in head and 6379 not in worker  # only the head serves the GCS
    assert 8265 not in head and 10001 not in head  # no dashboard, no Ray client server


@pytest.mark.netns
@pytest.mark.skipif(cc.can_run() is not None, reason=f"cluster check: {cc.can_run()}")
def test_cluster_check__three_hosts_survive_losing_a_worker_host_with_identical_rows() -> None:
    ref = os.environ.get("CLUSTER_REFERENCE")  # a single-machine smoke run (CI passes its own)
    assert cc.main(["--reference", ref] if ref else []) == 0
