"""MLflow logger: a SQLite tracking store at ``RUN/tracking/mlflow/mlflow.db``, MLflow's
recommended local backend (``mlflow ui --backend-store-uri sqlite:///RUN/tracking/mlflow/mlflow.db``;
``mlflow.set_tracking_uri`` with that URI, then ``mlflow.search_runs``; no environment
variable needed; docs/decisions/0204), experiment = the grid's name, one run per cell.

The run is named by method, N, p, seed and cell id (``CellInfo.run_name``; tag ``cell_id``)
and carries the cell's config as params; metrics ``train.<metric>`` per update (step = episodes trained) and
``eval.<mode>.<metric>`` at the end (``sample@0.5`` as ``sample_t0.5``); status FINISHED or FAILED. A resumed cell
continues
its run (found by the ``cell_id`` tag). Uses ``MlflowClient`` on an explicit store URI, so
nothing global (``mlflow.set_tracking_uri``, an active run) is touched.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from bench.tracking import flat_params
from bench.tracking.observers import CellInfo, Observer, Row, update_metrics

MAX_PARAM = 500  # characters of a param value kept (MLflow's limit is 6000)
BATCH = 900  # metrics per log_batch call (MLflow's limit is 1000)


def mlflow_name(mode: str) -> str:
    """An execution mode in an MLflow metric name, which may not hold '@':
    ``sample@0.5`` -> ``sample_t0.5``."""
    return mode.replace("@", "_t")


DB_NAME = "mlflow.db"  # the SQLite file under RUN/tracking/mlflow/


def store_uri(root: Path) -> str:
    """The tracking URI of a run's store, ``sqlite:////abs/RUN/tracking/mlflow/mlflow.db``
    (``root`` is RUN/tracking)."""
    return "sqlite:///" + (Path(root) / "mlflow" / DB_NAME).resolve().as_posix()


def artifact_uri(root: Path) -> str:
    """Where the experiment's artifacts would go (none are logged): beside the database, not
    ./mlruns of the working directory (MLflow's default for a database store)."""
    return (Path(root) / "mlflow" / "artifacts").resolve().as_uri()


class MlflowLogger(Observer):
    def __init__(self, root: Path, grid: str) -> None:
        self.root, self.grid = Path(root), grid
        self.client: Any = None  # opened at the first event: nothing is written before the run starts
        self.runs: dict[str, str] = {}

    def _open(self) -> None:
        from mlflow.tracking import MlflowClient

        (self.root / "mlflow").mkdir(parents=True, exist_ok=True)
        quiet = [logging.getLogger(name) for name in ("mlflow.store.db.utils", "alembic")]
        levels = [log.level for log in quiet]
        for log in quiet:  # creating the database's tables logs INFO lines into the run's output
            log.setLevel(logging.WARNING)
        try:
            self.client = MlflowClient(tracking_uri=store_uri(self.root))
            exp = self.client.get_experiment_by_name(self.grid)
        finally:
            for log, level in zip(quiet, levels, strict=True):
                log.setLevel(level)
        self.experiment_id = exp.experiment_id if exp is not None else self.client.create_experiment(
            self.grid, artifact_location=artifact_uri(self.root))

    def _run_id(self, cell: CellInfo) -> str:
        if cell.cell_id in self.runs:
            return self.runs[cell.cell_id]
        if self.client is None:
            self._open()
        found = self.client.search_runs([self.experiment_id], f"tags.cell_id = '{cell.cell_id}'",
                                        max_results=1)
        if found:
            run_id = found[0].info.run_id
            self.client.update_run(run_id, status="RUNNING")
        else:
            run = self.client.create_run(self.experiment_id, run_name=cell.run_name(),
                                         tags={"cell_id": cell.cell_id, "method": cell.method,
                                               "label": cell.label})
            run_id = run.info.run_id
            from mlflow.entities import Param

            params = [Param(k, str(v)[:MAX_PARAM]) for k, v in flat_params(cell.config).items()]
            for k in range(0, len(params), 100):
                self.client.log_batch(run_id, params=params[k:k + 100])
        self.runs[cell.cell_id] = run_id
        return run_id

    def on_cell_start(self, cell: CellInfo) -> None:
        self._run_id(cell)

    def _log(self, run_id: str, metrics: list[Any]) -> None:
        for k in range(0, len(metrics), BATCH):
            self.client.log_batch(run_id, metrics=metrics[k:k + BATCH])

    def on_train_rows(self, cell: CellInfo, rows: Sequence[Row]) -> None:
        from mlflow.entities import Metric

        stamp = int(time.time() * 1000)
        metrics = [Metric(f"train.{key}", value, stamp, step)
                   for step, values in update_metrics(rows, cell.batch_episodes) for key, value in values.items()]
        self._log(self._run_id(cell), metrics)

    def on_eval(self, cell: CellInfo, summary: Mapping[str, Mapping[str, float]]) -> None:
        from mlflow.entities import Metric

        stamp, step = int(time.time() * 1000), int(cell.config.get("episodes", 0))
        metrics = [Metric(f"eval.{mlflow_name(mode)}.{key}", value, stamp, step)
                   for mode, values in summary.items() for key, value in values.items()]
        self._log(self._run_id(cell), metrics)

    def on_cell_end(self, cell: CellInfo, status: str, error: str) -> None:
        run_id = self._run_id(cell)
        if error:
            self.client.set_tag(run_id, "error", error[:MAX_PARAM])
        self.client.set_terminated(run_id, "FINISHED" if status == "done" else "FAILED")
        self.runs.pop(cell.cell_id, None)

    def close(self) -> None:
        for run_id in self.runs.values():  # cells still running when the run stopped
            self.client.set_terminated(run_id, "KILLED")
        self.runs.clear()
