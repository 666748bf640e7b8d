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
    f"registry.register('toy', {TOY_PATH!r}); "
    "from bench.cli import main; sys.argv = ['bench'] + sys.argv[1:]; main()"
)


def cli_argv(*args: str) -> list[str]:
    return [sys.executable, "-c", CLI_WITH_TOY, *args]


@pytest.fixture
def toy() -> Iterator[str]:
    """Register the toy method in the driver's registry for the test."""
    registry.register("toy", TOY_PATH)
    yield "toy"
    registry.unregister("toy")


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

    from bench.execute.ray_cluster import OBJECT_STORE_BYTES, _loopback_only

    with _loopback_only():
        ray.init(address="local", num_cpus=2, object_store_memory=OBJECT_STORE_BYTES, include_dashboard=False,
                 log_to_driver=False, logging_level="ERROR", _node_ip_address="127.0.0.1")
    yield
    ray.shutdown()


def write_finished_store(out: Path, grid: Any, checksums: bool = False) -> None:
    """A complete run directory for ``grid`` computed in this process (no Ray), written with
    the same store calls and in the same order as the runner; ``checksums``: recorded in
    checksums.json as by this bench's runner (else a store of an older bench)."""
    from bench.execute.plan import cell_spec, plan_run
    from bench.execute.worker import CellWorker
    from bench.store.run_store import RunStore
    from bench.store.schema import SCHEMA_VERSION

    store = RunStore(out)
    states, _ = plan_run(store, grid, fresh=True)
    store.write_manifest({"schema_version": SCHEMA_VERSION, "grid": grid.name,
                          "runs": [{"grid": grid.name, "checksums": 1}] if checksums else []})
    if checksums:
        store.integrity().start_recording()
    worker = CellWorker()
    for st in states:
        spec, state, first = cell_spec(st.cell), None, 0
        while True:
            res = worker.train_chunk(spec, [state] if state is not None else [], st.iterations, 2)
            if res["rows"]:
                store.write_train_part(st.cell_id, first, res["rows"])
            state, st.iterations, first = res["state"], res["iterations"], res["episodes_done"]
            store.write_checkpoint(st.cell_id, {
                "cell": st.cell.canonical_json(), "method": st.cell.method, "iterations": st.iterations,
                "episodes_done": first, "finished": res["finished"], "wall_s": 0.0,
                "peak_mem_mb": 0.0, "attempts": 1, "state": state})
            if res["finished"]:
                break
        rows = [r for m, c in st.eval_units() for r in worker.eval_chunk(spec, [state], c, m)["rows"]]
        store.write_eval(st.cell_id, [r for r in rows if r["episode"] < st.cell.eval_episodes],
                         {"wall_s": 0.0, "attempts": 1, "train_episodes_done": first})
        st.phase, st.attempts, st.episodes_done = "done", 1, first
    store.write_cells([st.row(grid.name) for st in states])


def store_with_params(out: Path, cid: str, **old: Any) -> None:
    """Rewrite cells.parquet as if cell ``cid`` had been run when some method parameters
    (defaults) differed: ``old`` replaces or adds those fields of its ``params_json``."""
    import json

    from bench.store.run_store import RunStore

    store = RunStore(out)
    cells = store.read_cells()
    i = cells.index[cells["cell_id"] == cid][0]
    cells.loc[i, "params_json"] = json.dumps({**json.loads(cells.loc[i, "params_json"]), **old}, sort_keys=True)
    store.write_cells(cells.to_dict("records"))


def run_cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    """``bench ARGS`` in-process: (exit status, stdout, stderr)."""
    from bench.cli import main

    with pytest.raises(SystemExit) as exc:
        main(list(args))
    out, err = capsys.readouterr()
    return int(exc.value.code or 0), out, err


def one_error_line(err: str, *needles: str) -> None:
    """``err`` is one ``bench: error:`` line holding every needle."""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("bench: error: ") and "Traceback" not in err, err
    for n in needles:
        assert n in err, err


@pytest.fixture
def one_cell_run(toy: str, tmp_path: Path) -> Path:
    """A finished run directory of one toy cell (no checksums: as an older bench wrote it)."""
    from bench.design.grid_files import load_grid_file

    grid = load_grid_file(write_grid_file(tmp_path / "g.toml", toy_spec(), {"seed": [0]}))
    write_finished_store(tmp_path / "run", grid)
    return tmp_path / "run"


def as_written_by_the_bench(out: Path) -> None:
    """Record the current bytes of every stored file in the run's checksums, as if the bench
    itself had written them (a test's stand-in for an older bench or a crash that left a
    short file), so the rerun sees an incomplete cell rather than outside damage."""
    from bench.store.run_store import RunStore

    checksums = RunStore(out).integrity()
    checksums.start_recording()
    for path in sorted(p for p in Path(out).rglob("*") if p.is_file() and p.suffix in (".parquet", ".pt")):
        checksums.before_write(path, path.read_bytes())
