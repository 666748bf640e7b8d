"""A two-node Ray cluster (ray.cluster_utils.Cluster) runs a grid and survives losing a
node midway; `bench run --address` joins an existing cluster. Runtime: ~30-60 s on 2 shared cores."""
from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from bench.design.cells import Cell
from bench.design.grids import Grid
from bench.execute.runner import run_grid
from bench.store.run_store import RunStore
from tests.bench.conftest import REPO, cli_argv, toy_spec


@pytest.fixture
def two_nodes() -> Iterator[tuple[object, object]]:
    import ray
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    node = cluster.add_node(num_cpus=1)
    ray.init(address=cluster.address, log_to_driver=False, logging_level="ERROR")
    cluster.wait_for_nodes()
    try:
        yield cluster, node
    finally:
        ray.shutdown()
        cluster.shutdown()


@pytest.mark.slow
def test_run__two_node_cluster_survives_removing_a_node_midway(toy: str, two_nodes: tuple, tmp_path: Path) -> None:
    import ray

    cluster, node = two_nodes
    assert int(ray.cluster_resources()["CPU"]) == 2
    grid = Grid("toygrid", "cluster", tuple(
        Cell.make(**toy_spec(seed=s, episodes=12, params={"sleep_s": 0.5})) for s in range(4)))
    removed: list[bool] = []
    timer: list[threading.Timer] = []
    training: set[str] = set()

    def remove() -> None:
        cluster.remove_node(node)
        removed.append(True)

    def on_event(kind: str, st: object) -> None:
        if kind == "train_chunk":
            training.add(st.cell_id)  # type: ignore[attr-defined]
        if len(training) >= 2 and not timer:
            # Both workers are mid-cell. The event comes before the driver submits that cell's
            # next chunk, so the node goes 0.2 s later, from another thread: by then both
            # workers have a chunk (0.5 s) in flight, whichever of them the node holds.
            timer.append(threading.Timer(0.2, remove))
            timer[0].start()

    summary = run_grid(grid, tmp_path / "run", workers=2, checkpoint_every=1, on_event=on_event)
    for t in timer:  # the removal has finished before the checks
        t.join()
    assert removed, "the node was never removed"
    assert (summary.done, summary.failed) == (4, 0)
    store = RunStore(tmp_path / "run")
    train = store.read_train()
    assert not train.duplicated(["cell_id", "episode"]).any()
    assert train.groupby("cell_id")["episode"].apply(sorted).apply(list).tolist() == [list(range(12))] * 4
    assert len(store.read_eval()) == 4 * 5 * 3  # argmax, sample, sample@0.5
    cells = store.read_cells()
    assert (cells["status"] == "done").all()
    assert (cells["attempts"] >= 2).any(), "no cell lost its worker with the node"


@pytest.mark.slow
def test_cli__address_joins_an_existing_cluster(tmp_path: Path) -> None:
    import os
    import subprocess

    from ray.cluster_utils import Cluster

    grid = tmp_path / "g.toml"
    grid.write_text('[base]\nmethod = "pibt"\nlayout = "tiny"\nepisodes = 0\nhorizon = 20\n'
                    'eval_episodes = 4\n[axes]\nn_robots = [4, 8]\nloss_p = [0.2]\n')
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    address = cluster.address
    try:
        proc = subprocess.run(
            cli_argv("run", "--grid-file", str(grid), "--out", str(tmp_path / "run"), "--address", address),
            cwd=REPO, capture_output=True, text=True, timeout=240, env={**os.environ, "CI": "true"})
        # this checkout's code in the driver, like the workers the in-process head starts
    finally:
        cluster.shutdown()
    assert proc.returncode == 0, proc.stderr
    manifest = RunStore(tmp_path / "run").require_run()
    assert manifest["ray"] == address and manifest["workers"] == 1
    assert (RunStore(tmp_path / "run").read_cells()["status"] == "done").all()
