"""Shared fixtures of the bench tests: the toy method, tiny cells, Ray, store snapshots."""
from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from algorithms import registry
from tests.bench.toy_method import TOY_PATH

REPO = Path(__file__).resolve().parents[2]

# A subprocess that runs the `bench` CLI with the toy method registered (the registry dict
# of a fresh interpreter does not know it).
CLI_WITH_TOY = (
    "import sys; from algorithms import registry; "
    f"registry.METHODS['toy'] = {TOY_PATH!r}; "
    "from bench.cli import main; sys.argv = ['bench'] + sys.argv[1:]; main()"
)


def cli_argv(*args: str) -> list[str]:
    return [sys.executable, "-c", CLI_WITH_TOY, *args]


@pytest.fixture
def toy(monkeypatch: pytest.MonkeyPatch) -> str:
    """Register the toy method in the driver's registry for the test."""
    monkeypatch.setitem(registry.METHODS, "toy", TOY_PATH)
    return "toy"


def toy_spec(**kw: Any) -> dict[str, Any]:
    """A tiny toy cell: 4 robots on `tiny`, horizon 12, 8 training episodes, 5 eval episodes."""
    params = {"batch_episodes": 2, "eval_chunk": 2, **kw.pop("params", {})}
    spec = dict(method="toy", n_robots=4, loss_p=0.2, layout="tiny", episodes=8, horizon=12,
                eval_episodes=5, params=params)
    spec.update(kw)
    return spec


def write_grid_file(path: Path, base: dict[str, Any], axes: dict[str, list[Any]],
                    name: str = "toygrid") -> Path:
    """A TOML grid file: ``base`` (may hold a ``params`` table) crossed with ``axes``."""
    lines = [f'name = "{name}"', "[base]"]
    lines += [f"{k} = {json.dumps(v)}" for k, v in base.items() if k != "params"]
    if base.get("params"):
        lines.append("[base.params]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in base["params"].items()]
    lines.append("[axes]")
    lines += [f'"{k}" = {json.dumps(v)}' for k, v in axes.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def snapshot(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` with its bytes (to assert a store is unchanged)."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def ray_local() -> Iterator[None]:
    """An embedded 2-CPU Ray for the module; the runner uses it and leaves it running."""
    import ray

    from bench.ray_cluster import OBJECT_STORE_BYTES

    ray.init(num_cpus=2, object_store_memory=OBJECT_STORE_BYTES, include_dashboard=False,
             log_to_driver=False, logging_level="ERROR", _node_ip_address="127.0.0.1")
    yield
    ray.shutdown()
