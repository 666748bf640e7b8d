"""bench run --log: the values TensorBoard, MLflow and W&B (offline) hold are the stored
train rows (per update) and the evaluation means; a logger that fails never fails a cell.
Runtime: ~40 s on 2 shared cores (one tiny 2-cell run on Ray for the module)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bench.design.cells import Cell
from bench.design.grids import Grid
from bench.execute.runner import run_grid
from bench.store.run_store import RunStore
from bench.tracking import make_observer, parse_log
from bench.tracking.observers import Observer, update_metrics
from envs.errors import BenchError
from tests.bench.conftest import toy_spec

BATCH = 2  # toy_spec's batch_episodes
TRAIN_KEYS = ["team_return", "success_rate", "collision_rate", "steps", "actor_loss", "wall_s"]


class Recorder(Observer):
    """Every call, in order (a user's logger in a few lines)."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, str]] = []
        self.rows: dict[str, list[dict]] = {}

    def on_cell_start(self, cell):
        self.calls.append(("start", cell.cell_id))

    def on_train_rows(self, cell, rows):
        self.calls.append(("train", cell.cell_id))
        self.rows.setdefault(cell.cell_id, []).extend(dict(r) for r in rows)

    def on_eval(self, cell, summary):
        self.calls.append(("eval", cell.cell_id))

    def on_cell_end(self, cell, status, error):
        self.calls.append((status, cell.cell_id))


class Broken(Observer):
    def on_train_rows(self, cell, rows):
        raise RuntimeError("tracker down")


@pytest.fixture(scope="module")
def tracked_run(ray_local, tmp_path_factory) -> tuple[Path, Recorder]:
    from algorithms import registry
    from tests.bench.toy_method import TOY_PATH

    registry.register("toy", TOY_PATH)
    out = tmp_path_factory.mktemp("tracked") / "run"
    grid = Grid("toygrid", "test", tuple(Cell.make(**toy_spec(seed=s)) for s in (0, 1)))
    rec = Recorder()
    obs = make_observer(parse_log("tensorboard,mlflow,wandb"), out, grid.name, extra=[Broken(), rec])
    summary = run_grid(grid, out, workers=2, checkpoint_every=2, observer=obs)
    obs.close()
    assert summary.done == 2
    assert list(obs.disabled.values()) == ["RuntimeError: tracker down"]  # only the broken one
    return out, rec


def _expected_updates(out: Path) -> pd.DataFrame:
    """Per cell and update: the mean of the stored train rows (NaN left out), at step =
    episodes trained after the update (computed here with pandas, independently)."""
    train = RunStore(out).read_train()
    train["step"] = (train["episode"] // BATCH + 1) * BATCH
    return train.groupby(["cell_id", "step"])[TRAIN_KEYS].mean().reset_index()


def test_tracking__tensorboard_event_files_hold_the_stored_train_rows_per_update(tracked_run) -> None:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    out, _ = tracked_run
    expected = _expected_updates(out)
    evals = RunStore(out).read_eval()
    cells = RunStore(out).read_cells().set_index("cell_id")
    folders = {p.name for p in (out / "tracking" / "tensorboard").iterdir()}
    folder = {cid: f"toy_N4_p0.2_seed{cells.loc[cid, 'seed']}_{cid}" for cid in cells.index}  # readable runs
    assert folders == set(folder.values())
    for cid, exp in expected.groupby("cell_id"):
        acc = EventAccumulator(str(out / "tracking" / "tensorboard" / folder[cid]))
        acc.Reload()
        for key in TRAIN_KEYS:
            events = acc.Scalars(f"train/{key}")
            assert [e.step for e in events] == list(exp["step"])
            np.testing.assert_allclose([e.value for e in events], exp[key], rtol=1e-6)  # float32
        ev = evals[(evals["cell_id"] == cid) & (evals["execution"] == "sample@0.5")]
        got = acc.Scalars("eval/sample@0.5/success_rate")
        assert len(got) == 1 and got[0].value == pytest.approx(ev["success_rate"].mean(), rel=1e-6)
        config = acc.Tensors("config/text_summary")[0].tensor_proto.string_val[0].decode()
        seed = int(RunStore(out).read_cells().set_index("cell_id").loc[cid, "seed"])
        assert f'"seed": {seed}' in config and '"batch_episodes": 2' in config


def test_tracking__mlflow_store_holds_one_run_per_cell_with_its_config_and_the_stored_values(tracked_run) -> None:
    from mlflow.tracking import MlflowClient

    from bench.tracking.mlflow_store import store_uri

    out, _ = tracked_run
    client = MlflowClient(tracking_uri=store_uri(out / "tracking"))
    exp = client.get_experiment_by_name("toygrid")
    runs = {r.data.tags["cell_id"]: r for r in client.search_runs([exp.experiment_id])}
    cells = RunStore(out).read_cells().set_index("cell_id")
    assert set(runs) == set(cells.index)
    for cid, run in runs.items():
        assert run.info.run_name == f"toy N=4 p=0.2 seed={cells.loc[cid, 'seed']} {cid}"
    expected = _expected_updates(out)
    evals = RunStore(out).read_eval()
    for cid, run in runs.items():
        assert run.info.status == "FINISHED"
        assert run.data.params["seed"] == str(cells.loc[cid, "seed"])
        assert run.data.params["n_robots"] == "4" and run.data.params["params.batch_episodes"] == "2"
        exp_c = expected[expected["cell_id"] == cid]
        for key in TRAIN_KEYS:
            hist = sorted(client.get_metric_history(run.info.run_id, f"train.{key}"), key=lambda m: m.step)
            assert [m.step for m in hist] == list(exp_c["step"])
            np.testing.assert_allclose([m.value for m in hist], exp_c[key], rtol=1e-12)
        argmax = evals[(evals["cell_id"] == cid) & (evals["execution"] == "argmax")]
        assert run.data.metrics["eval.argmax.team_return"] == pytest.approx(argmax["team_return"].mean(), rel=1e-12)
        assert run.data.metrics["eval.sample_t0.5.episodes"] == 5


def test_tracking__mlflow_search_runs_reads_the_store_with_no_environment_variable(tracked_run) -> None:
    out, _ = tracked_run
    code = ("import mlflow, sys; mlflow.set_tracking_uri(sys.argv[1]); "
            "df = mlflow.search_runs(experiment_names=['toygrid']); "
            "print(sorted(df['tags.mlflow.runName'])); print(sorted(df['status']))")
    from bench.tracking.mlflow_store import store_uri

    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    done = subprocess.run([sys.executable, "-c", code, store_uri(out / "tracking")], capture_output=True, text=True,
                          env=env, check=False)
    assert done.returncode == 0, done.stderr
    assert "toy N=4 p=0.2 seed=0 " in done.stdout and "toy N=4 p=0.2 seed=1 " in done.stdout
    assert "['FINISHED', 'FINISHED']" in done.stdout


def test_tracking__wandb_writes_one_offline_run_per_cell(tracked_run) -> None:
    out, _ = tracked_run
    files = sorted((out / "tracking" / "wandb").rglob("run-*.wandb"))
    cells = set(RunStore(out).read_cells()["cell_id"])
    assert {f.stem.removeprefix("run-") for f in files} == cells
    assert all(b"train/team_return" in f.read_bytes() for f in files)
    assert all(b"toy N=4 p=0.2 seed=" in f.read_bytes() for f in files)  # the readable run name


def test_tracking__observer_sees_each_cell_start_train_eval_end_in_order_and_the_stored_rows(tracked_run) -> None:
    out, rec = tracked_run
    train = RunStore(out).read_train()
    for cid in set(train["cell_id"]):
        kinds = [k for k, c in rec.calls if c == cid]
        assert kinds[0] == "start" and kinds[-2:] == ["eval", "done"]
        assert set(kinds[1:-2]) == {"train"}
        got = pd.DataFrame(rec.rows[cid])
        stored = train[train["cell_id"] == cid].sort_values("episode").reset_index(drop=True)
        pd.testing.assert_frame_equal(got[TRAIN_KEYS].astype(float), stored[TRAIN_KEYS].astype(float))


def test_update_metrics__mean_per_update_ignores_nan_and_keeps_a_shared_value_exactly() -> None:
    rows = [{"episode": 0, "team_return": 1.0, "loss": 0.1, "x": float("nan"), "ok": True},
            {"episode": 1, "team_return": 2.0, "loss": 0.1, "x": float("nan")},
            {"episode": 2, "team_return": 4.0, "loss": 0.3, "x": 5.0},
            {"episode": 3, "team_return": float("nan"), "loss": 0.3, "x": float("nan")}]
    assert update_metrics(rows, 2) == [(2, {"team_return": 1.5, "loss": 0.1}),
                                      (4, {"team_return": 4.0, "loss": 0.3, "x": 5.0})]


def test_parse_log__unknown_logger_is_one_clear_error() -> None:
    with pytest.raises(BenchError, match="--log: unknown logger 'tensorbored'"):
        parse_log("tensorbored")
    with pytest.raises(BenchError, match="--log nosuch.module:Logger: cannot import"):
        parse_log("nosuch.module:Logger")
    assert parse_log("TensorBoard, mlflow,tensorboard") == ["tensorboard", "mlflow"]


def test_docs_tracking__the_custom_logger_example_runs_as_written(
        ray_local, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    import re

    from algorithms import registry
    from tests.bench.conftest import REPO
    from tests.bench.toy_method import TOY_PATH

    registry.register("toy", TOY_PATH)
    page = (REPO / "docs" / "tracking.md").read_text()
    blocks = [b for b in re.findall(r"```python\n(.*?)```", page, flags=re.S) if "import mlflow" not in b]
    assert len(blocks) == 2 and "class BestReturn(Observer)" in blocks[0]
    grid = Grid("smoke", "test", tuple(Cell.make(**toy_spec(seed=s)) for s in (0, 1)))
    monkeypatch.setattr("bench.design.grids.get_grid", lambda name, seeds=None: grid)  # the toy grid, not smoke
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(blocks[0], "docs/tracking.md", "exec"), namespace)
    exec(compile(blocks[1], "docs/tracking.md", "exec"), namespace)
    printed = [ln for ln in capsys.readouterr().out.splitlines() if "best training return" in ln]
    train = RunStore(tmp_path / "results" / "smoke-mine").read_train()
    assert len(printed) == 2
    for cid, best in train.groupby("cell_id")["team_return"].max().items():
        line = next(ln for ln in printed if ln.startswith(cid))
        assert f"best training return {best:.2f}" in line and "argmax" in line
