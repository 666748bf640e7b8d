"""``bench run --device`` / ``bench eval --device``: a bad or absent device is one line and
exit status 2 before anything runs; the workers build the methods' networks on the device
(simulated here, tests/algorithms/fake_device.py) with the cpu's rows; a method that takes
no device is refused by name; the cell never names the device."""
from __future__ import annotations

import json

import pytest
import torch

from bench.cli import main
from bench.execute.quick_eval import quick_eval
from bench.execute.worker import CellWorker, build_method
from envs.errors import BenchError
from tests.algorithms.fake_device import fake_cuda


def _cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    with pytest.raises(SystemExit) as exc:
        main(list(args))
    return int(exc.value.code or 0), capsys.readouterr().err


@pytest.mark.parametrize("command", [["run", "--grid", "smoke"], ["eval", "--method", "decentralized"]])
@pytest.mark.parametrize(("device", "why"), [("cudaa", "not a torch device"), ("cuda", "no CUDA device")])
def test_a_bad_device_is_one_line(capsys: pytest.CaptureFixture[str], tmp_path, monkeypatch: pytest.MonkeyPatch,
                                  command: list[str], device: str, why: str) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    out = ["--out", str(tmp_path / "run")] if command[0] == "run" else []
    code, err = _cli(capsys, *command, *out, "--device", device)
    assert code == 2 and err.count("\n") == 1 and why in err and "--device" in err, err
    assert not (tmp_path / "run").exists()


def _eval(device: str) -> str:
    cell, rows = quick_eval("hierarchical", n_robots=6, layout="tiny", episodes=2, horizon=8, groups=3,
                            device=device)
    assert "device" not in cell.canonical_json()  # an execution choice, no cell field
    assert (cell.n_robots, cell.groups, cell.horizon, cell.eval_episodes) == (6, 3, 8, 2)
    return json.dumps([{k: v for k, v in r.items() if k != "wall_s"} for r in rows], default=float)  # NaN-safe


def test_eval_on_the_device_gives_the_cpu_rows() -> None:
    want = _eval("cpu")
    with fake_cuda():
        got = _eval("cuda")
    assert got == want


def test_a_worker_trains_on_its_device() -> None:
    spec = {"cell_id": "c", "method_path": "decentralized", "seed": 1, "episodes": 2,
            "env": {"n_robots": 4, "layout": "tiny", "horizon": 8, "loss_p": 0.2},
            "params": {"batch_episodes": 2}}
    want = CellWorker().train_chunk(spec, [], 0, 1)
    with fake_cuda():
        got = CellWorker("cuda").train_chunk(spec, [], 0, 1)
    def strip(rows: list[dict]) -> str:
        return json.dumps([{k: v for k, v in r.items() if k != "wall_s"} for r in rows], default=float)

    assert strip(got["rows"]) == strip(want["rows"])
    assert all(t.device.type == "cpu" for t in got["state"]["actor"].values())  # checkpoints on the host


def test_a_method_without_a_device_argument_is_refused(toy: str) -> None:
    spec = {"method_path": toy, "seed": 0, "env": {"n_robots": 4, "layout": "tiny", "horizon": 8},
            "params": {}}
    assert build_method(spec).learned  # the cpu: built as before
    with pytest.raises(BenchError, match="takes no device"):
        build_method(spec, "cuda")


class _Refused(Exception):
    """Stands in for the Ray executor: records how the runner asked for its workers."""


def test_run_grid_asks_ray_for_gpu_shares_and_records_the_device(toy: str, tmp_path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    import bench.execute.runner as runner
    from bench.design.grid_files import load_grid_file
    from bench.execute.ray_cluster import RayContext
    from bench.store.run_store import RunStore
    from tests.bench.conftest import toy_spec, write_grid_file

    asked: dict = {}

    def executor(worker_cls, capacity, ctx, **kw):  # noqa: ANN001, ANN202 - RayExecutor's signature
        asked.update(kw, capacity=capacity)
        raise _Refused

    monkeypatch.setattr(runner, "connect", lambda *a, **k: RayContext(False, "none", 2))
    monkeypatch.setattr(runner, "RayExecutor", executor)
    grid = load_grid_file(write_grid_file(tmp_path / "g.toml", toy_spec(), {"seed": [0, 1]}))
    with pytest.raises(_Refused):
        runner.run_grid(grid, tmp_path / "run", workers=2, device="cuda:0")
    assert asked == {"capacity": 2, "worker_args": ("cuda:0",), "num_gpus": 0.5}
    record = RunStore(tmp_path / "run").read_manifest()["runs"][-1]
    assert record["device"] == "cuda:0"
    cells = RunStore(tmp_path / "run").read_cells()
    assert "cuda" not in cells.to_json()  # no cell names the device

    asked.clear()
    with pytest.raises(_Refused):
        runner.run_grid(grid, tmp_path / "cpu", workers=2)
    assert asked == {"capacity": 2}  # the cpu: workers as before
    assert "device" not in RunStore(tmp_path / "cpu").read_manifest()["runs"][-1]
