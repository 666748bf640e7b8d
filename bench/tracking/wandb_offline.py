"""Weights & Biases logger, offline: ``RUN/tracking/wandb/`` (``wandb sync`` uploads it
later), project = the grid's name, one run per cell (id = the cell id, name =
``CellInfo.run_name``: method, N, p, seed and cell id; the cell's config as the run config).
``train/<metric>`` per update with ``episodes`` (episodes trained) as its x-axis,
``eval/<mode>/<metric>`` in the run summary. Never goes online:
``mode="offline"`` and ``WANDB_MODE`` is not consulted.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from bench.tracking.observers import CellInfo, Observer, Row, update_metrics


class WandbLogger(Observer):
    def __init__(self, root: Path, grid: str) -> None:
        self.dir = Path(root) / "wandb"
        self.project = grid
        self.runs: dict[str, Any] = {}

    def _run(self, cell: CellInfo) -> Any:
        if cell.cell_id not in self.runs:
            import wandb

            self.dir.mkdir(parents=True, exist_ok=True)
            run = wandb.init(project=self.project, name=cell.run_name(), id=cell.cell_id, dir=str(self.dir),
                             config=cell.config, mode="offline", resume="allow", reinit="create_new",
                             tags=[cell.method], settings=wandb.Settings(silent=True, console="off"))
            run.define_metric("episodes")
            run.define_metric("train/*", step_metric="episodes")
            self.runs[cell.cell_id] = run
        return self.runs[cell.cell_id]

    def on_cell_start(self, cell: CellInfo) -> None:
        self._run(cell)

    def on_train_rows(self, cell: CellInfo, rows: Sequence[Row]) -> None:
        run = self._run(cell)
        for step, metrics in update_metrics(rows, cell.batch_episodes):
            run.log({"episodes": step, **{f"train/{k}": v for k, v in metrics.items()}})

    def on_eval(self, cell: CellInfo, summary: Mapping[str, Mapping[str, float]]) -> None:
        run = self._run(cell)
        for mode, metrics in summary.items():
            for key, value in metrics.items():
                run.summary[f"eval/{mode}/{key}"] = value

    def on_cell_end(self, cell: CellInfo, status: str, error: str) -> None:
        run = self.runs.pop(cell.cell_id, None)
        if run is not None:
            run.finish(exit_code=0 if status == "done" else 1)

    def close(self) -> None:
        for run in self.runs.values():
            run.finish(exit_code=1)
        self.runs.clear()
