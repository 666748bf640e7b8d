"""``bench run --cell-threads K``: a bad count is one line and exit status 2 before anything
runs; the count reaches torch in the worker for training and evaluation; each worker asks Ray
for K CPUs; the run record, checkpoint and eval file of every cell started with K > 1 say K,
and a resumed cell keeps the count it started with (docs/decisions/0242)."""
from __future__ import annotations

from pathlib import Path

import pytest
import torch

from bench.cli import main
from bench.design.cells import Cell
from bench.execute.plan import cell_spec
from bench.execute.worker import CellWorker
from bench.store.run_store import RunStore
from envs.errors import BenchError
from tests.bench.conftest import toy_spec
from tests.bench.toy_method import ToyMethod


@pytest.fixture(autouse=True)
def _restore_threads():  # noqa: ANN202 - a fixture
    before = torch.get_num_threads()
    yield
    torch.set_num_threads(before)


def _cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    with pytest.raises(SystemExit) as exc:
        main(list(args))
    return int(exc.value.code or 0), capsys.readouterr().err


@pytest.mark.parametrize(("args", "why"), [
    (["--cell-threads", "0"], "from 1 to 64"), (["--cell-threads", "auto"], "no auto"),
    (["--cell-threads", "65"], "from 1 to 64"), (["--cell-threads", "2", "--stack-seeds", "3"], "one thread only"),
])
def test_a_bad_cell_threads_is_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path, args: list[str],
                                        why: str) -> None:
    code, err = _cli(capsys, "run", "--grid", "smoke", "--out", str(tmp_path / "run"), *args)
    assert code == 2 and err.count("\n") == 1 and why in err and "--cell-threads" in err, err
    assert not (tmp_path / "run").exists()


def test_the_cells_thread_count_reaches_torch_in_the_worker(toy: str, monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[int] = []
    train, evaluate = ToyMethod.train_iteration, ToyMethod.evaluate

    def train_seen(self):  # noqa: ANN001, ANN202
        seen.append(torch.get_num_threads())
        return train(self)

    def eval_seen(self, *args):  # noqa: ANN001, ANN202
        seen.append(torch.get_num_threads())
        return evaluate(self, *args)

    monkeypatch.setattr(ToyMethod, "train_iteration", train_seen)
    monkeypatch.setattr(ToyMethod, "evaluate", eval_seen)
    spec = cell_spec(Cell.make(**toy_spec(episodes=4)))
    worker = CellWorker()
    res = worker.train_chunk({**spec, "threads": 2}, [], 0, 1)
    worker.eval_chunk({**spec, "threads": 2}, [res["state"]], 0, "argmax")
    assert seen == [2, 2]
    worker.train_chunk(spec, [res["state"]], res["iterations"], 1)  # no count: one thread, as before
    worker.eval_chunk(spec, [res["state"]], 0, "argmax")
    assert seen == [2, 2, 1, 1]


class _Refused(Exception):
    """Stands in for the Ray executor: its argument is how the runner asked for its workers."""


def _refuse(worker_cls: type, capacity: int, ctx: object, **options: object) -> None:
    raise _Refused({"capacity": capacity, **options})


def test_run_grid_asks_ray_for_k_cpus_per_worker_and_records_k(toy: str, tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    import bench.execute.runner as runner
    from bench.design.grid_files import load_grid_file
    from bench.execute.ray_cluster import RayContext
    from tests.bench.conftest import write_grid_file

    monkeypatch.setattr(runner, "connect", lambda *a, **k: RayContext(False, "none", 4))
    monkeypatch.setattr(runner, "RayExecutor", _refuse)
    grid = load_grid_file(write_grid_file(tmp_path / "g.toml", toy_spec(), {"seed": [0, 1]}))
    with pytest.raises(_Refused) as asked:
        runner.run_grid(grid, tmp_path / "run", cell_threads=2)
    assert asked.value.args[0] == {"capacity": 2, "worker_args": ("cpu", 2), "num_cpus": 2}  # 4 CPUs: 2 x 2
    assert RunStore(tmp_path / "run").read_manifest()["runs"][-1]["cell_threads"] == 2
    with pytest.raises(BenchError, match="more threads than the 4 CPUs"):
        runner.run_grid(grid, tmp_path / "five", cell_threads=5)
    assert not (tmp_path / "five").exists()


@pytest.mark.usefixtures("ray_local")
def test_cells_record_their_count_and_a_resumed_cell_keeps_it(toy: str, tmp_path: Path) -> None:
    from bench.design.grids import Grid
    from bench.execute.runner import run_grid

    grid = Grid("toygrid", "test", tuple(Cell.make(**toy_spec(seed=s)) for s in (0, 1)))
    first, second = (c.cell_id for c in grid.cells)
    started: list[str] = []

    def interrupt(kind: str, st: object) -> None:
        if kind == "train_chunk":  # the first cell's first chunk is stored: stop
            started.append(st.cell_id)  # type: ignore[attr-defined]
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_grid(grid, tmp_path / "run", workers=1, checkpoint_every=1, cell_threads=2, on_event=interrupt)
    cut = started[0]
    store = RunStore(tmp_path / "run")
    assert store.read_checkpoint(cut, "toy")["cell_threads"] == 2
    run_grid(grid, tmp_path / "run", workers=1, checkpoint_every=1)  # resumed with the default, 1
    runs = store.read_manifest()["runs"]
    assert runs[0]["cell_threads"] == 2 and "cell_threads" not in runs[1]
    other = second if cut == first else first
    assert store.eval_meta(cut)["cell_threads"] == 2  # trained on with the count it started with
    assert "cell_threads" not in store.eval_meta(other)  # started in the default run: one thread
    assert "cell_threads" not in store.read_checkpoint(other, "toy")
