"""Experiment tracking for ``bench run --log tensorboard,mlflow,wandb``.

Each logger is a ``bench.tracking.observers.RunObserver`` in a module of its own; this module
names them, checks that the chosen ones can be imported (before a run writes anything),
and builds one observer that feeds them all. Every logger writes under ``RUN/tracking/``:
one tracker run per cell, named by the cell id, with the cell's config as parameters;
per training update the mean of the update's train rows (``bench.tracking.observers.update_metrics``)
at step = episodes trained, and at the end the evaluation means per execution mode.

May import: envs, algorithms, bench.store, bench.about (the layers of .importlinter).
"""
from __future__ import annotations

import contextlib
import importlib
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from bench.tracking.observers import Observers, RunObserver
from envs.errors import BenchError

TRACKING_DIR = "tracking"
# name -> (module of its logger class, class, the library it needs, its pip name)
LOGGERS: dict[str, tuple[str, str, str, str]] = {
    "tensorboard": ("bench.tracking.tb", "TensorBoardLogger", "torch.utils.tensorboard", "tensorboard"),
    "mlflow": ("bench.tracking.mlflow_store", "MlflowLogger", "mlflow", "mlflow-skinny"),
    "wandb": ("bench.tracking.wandb_offline", "WandbLogger", "wandb", "wandb"),
}


def parse_log(value: str | None) -> list[str]:
    """``--log`` as a list of logger names; BenchError naming a bad or missing one."""
    if not value:
        return []
    names = [v.strip() if ":" in v else v.strip().lower() for v in value.split(",") if v.strip()]
    for name in names:
        if ":" in name:
            _user_logger(name)
        elif name not in LOGGERS:
            raise BenchError(f"--log: unknown logger {name!r}; choose from {', '.join(LOGGERS)} "
                             "or give your own as module:Class (comma-separated)")
    for name in dict.fromkeys(n for n in names if ":" not in n):
        _, _, lib, pip_name = LOGGERS[name]
        try:
            importlib.import_module(lib)
        except ImportError as exc:
            raise BenchError(f"--log {name}: the {pip_name} package is not installed ({exc}); "
                             "install it with: pip install 'warehouse-marl-bench[track]'") from None
    return list(dict.fromkeys(names))


def make_observer(names: Sequence[str], run_dir: str | Path, grid: str,
                  extra: Sequence[RunObserver] = ()) -> Observers | None:
    """One observer for the named loggers (writing under ``run_dir/tracking/``) and any
    ``extra`` observers of your own; None when there is nothing to observe."""
    root = Path(run_dir) / TRACKING_DIR
    loggers: list[RunObserver] = []
    for name in names:
        if ":" in name:
            factory: Callable[..., Any] = _user_logger(name)
        else:
            module, cls, _, _ = LOGGERS[name]
            factory = getattr(importlib.import_module(module), cls)
        loggers.append(_made(name, factory, root, grid))
    loggers += list(extra)
    return Observers(loggers) if loggers else None


def _made(name: str, factory: Callable[..., Any], root: Path, grid: str) -> RunObserver:
    """``factory(root, grid)``; one BenchError naming ``--log NAME`` whatever the call raises,
    or when it returns something that is not an observer (D20: ``--log os:system``)."""
    try:
        logger = factory(root, grid)
    except BenchError:
        raise
    except Exception as exc:
        text = " ".join(str(exc).split())[:200]
        raise BenchError(f"--log {name}: calling it as {name}(tracking_dir, grid_name) failed "
                         f"({type(exc).__name__}: {text})") from None
    hooks = ("on_cell_start", "on_train_rows", "on_eval", "on_cell_end", "close")
    if not any(callable(getattr(logger, hook, None)) for hook in hooks):
        raise BenchError(f"--log {name}: {name}(tracking_dir, grid_name) returned {type(logger).__name__}, "
                         "not a logger (a bench.tracking.observers.RunObserver)")
    return logger


def _user_logger(path: str) -> Callable[..., Any]:
    """``module:Class`` of a logger of your own, called as ``Class(tracking_dir, grid_name)``."""
    module, _, name = path.partition(":")
    try:
        with contextlib.redirect_stdout(sys.stderr):  # its prints never mix into stdout
            return getattr(importlib.import_module(module), name)
    except Exception as exc:  # an outside module may raise anything at import
        raise BenchError(f"--log {path}: cannot import the logger ({type(exc).__name__}: {exc})") from None


def flat_params(config: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """A cell's config flattened to ``{"n_robots": 40, "params.hidden": 64, ...}``; lists
    and None as text (trackers take scalars and strings)."""
    out: dict[str, Any] = {}
    for k, v in config.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flat_params(v, key + "."))
        elif isinstance(v, (bool, int, float, str)):
            out[key] = v
        else:
            out[key] = str(v)
    return out
