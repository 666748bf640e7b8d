"""TensorBoard logger: ``RUN/tracking/tensorboard/<run>/`` event files, one run per cell, its
folder named by method, N, p, seed and cell id (``CellInfo.folder_name``; a folder named by the
cell id alone, written before, is continued).

Scalars ``train/<metric>`` per update (step = episodes trained) and ``eval/<mode>/<metric>``
at step = the cell's training episodes; the config as the run's hparams and as a ``config``
text (JSON). Written with ``torch.utils.tensorboard`` (the tensorboard package). A resumed
cell appends a new event file to the same folder; TensorBoard merges them by step.
"""
from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from bench.tracking import flat_params
from bench.tracking.observers import CellInfo, Observer, Row, update_metrics


class TensorBoardLogger(Observer):
    def __init__(self, root: Path, grid: str) -> None:
        self.root = Path(root) / "tensorboard"
        self.writers: dict[str, Any] = {}

    def _writer(self, cell: CellInfo) -> Any:
        if cell.cell_id not in self.writers:
            from torch.utils.tensorboard import SummaryWriter

            folder = self.root / cell.cell_id  # a run written before names stayed readable
            if not folder.is_dir():
                folder = self.root / cell.folder_name()
            self.writers[cell.cell_id] = SummaryWriter(log_dir=str(folder))
        return self.writers[cell.cell_id]

    def on_cell_start(self, cell: CellInfo) -> None:
        from torch.utils.tensorboard.summary import hparams

        w = self._writer(cell)
        w.add_text("config", "```\n" + json.dumps(cell.config, indent=1, sort_keys=True) + "\n```")
        params = flat_params(cell.config)
        exp, ssi, sei = hparams(params, {"eval/argmax/success_rate": float("nan")})
        fw = w._get_file_writer()
        for summary in (exp, ssi, sei):
            fw.add_summary(summary)
        w.flush()

    def on_train_rows(self, cell: CellInfo, rows: Sequence[Row]) -> None:
        w = self._writer(cell)
        for step, metrics in update_metrics(rows, cell.batch_episodes):
            for key, value in metrics.items():
                w.add_scalar(f"train/{key}", value, step)
        w.flush()

    def on_eval(self, cell: CellInfo, summary: Mapping[str, Mapping[str, float]]) -> None:
        w = self._writer(cell)
        step = int(cell.config.get("episodes", 0))
        for mode, metrics in summary.items():
            for key, value in metrics.items():
                w.add_scalar(f"eval/{mode}/{key}", value, step)
        w.flush()

    def on_cell_end(self, cell: CellInfo, status: str, error: str) -> None:
        w = self.writers.pop(cell.cell_id, None)
        if w is not None:
            if error:
                w.add_text("error", error)
            w.close()

    def close(self) -> None:
        for w in self.writers.values():
            w.close()
        self.writers.clear()
