"""Image build step: keep the byte code of what the bench imports, delete the rest (size).

Imports the modules a run, a report and a Ray worker load, then deletes every ``.pyc`` in
site-packages whose source module was not loaded. A module imported later anyway is
compiled in memory on import (the image's user cannot write /opt/venv): slower to import
once per process, never different in what it computes.
"""
from __future__ import annotations

import importlib
import sys
import sysconfig
from pathlib import Path

ENTRY_POINTS = (
    "bench.cli", "bench.execute.runner", "bench.execute.worker", "bench.execute.executor",
    "bench.store.run_store", "bench.execute.matrix",
    "reports", "reports.stats", "studies", "algorithms.registry", "envs.warehouse_v0",
    "torch", "ray", "ray.util", "ray.dashboard.agent", "ray._private.runtime_env.agent.main",
    "ray._private.log_monitor", "ray.scripts.scripts",
    "pandas", "pyarrow.parquet", "pyarrow.dataset", "matplotlib.pyplot", "seaborn",
    "scipy.stats", "rliable.metrics", "optuna", "pettingzoo", "gymnasium", "imageio", "typer", "rich",
)


def main() -> int:
    for name in ENTRY_POINTS:
        try:
            importlib.import_module(name)
        except Exception as exc:  # an optional entry point; its pyc just go
            print(f"prune_pyc: {name} not imported ({type(exc).__name__}: {exc})", file=sys.stderr)
    loaded = {Path(m.__file__).resolve() for m in list(sys.modules.values())
              if getattr(m, "__file__", None)}
    site = Path(sysconfig.get_paths()["purelib"])
    kept = removed = 0
    for pyc in site.rglob("__pycache__/*.pyc"):
        source = pyc.parent.parent / (pyc.name.split(".", 1)[0] + ".py")
        if source.resolve() in loaded:
            kept += pyc.stat().st_size
        else:
            removed += pyc.stat().st_size
            pyc.unlink()
    print(f"prune_pyc: kept {kept / 1e6:.0f} MB of byte code, removed {removed / 1e6:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
