"""Tuning seeds disjoint from every seed a published grid evaluates (Eimer et al. 2023).

A study trains replicate r of every configuration with ``replicate_seed(study seed, r)``
and evaluates every trial on the scenarios of ``eval_seed(study seed)``
(studies/schedule.py, studies/objective.py). A bench cell's seed roots both its training
and its evaluation scenarios. So a study whose training or evaluation seed equals a seed
that a committed grid under ``reproduction/`` evaluates would tune on that grid's test
scenarios; ``check_tuning_seeds`` refuses it before any trial runs, naming the seed and
the grid. The published seeds are read from every committed store's ``cells.parquet``
and every committed grid file (``reproduction/*.toml``), which may not have run yet.
"""
from __future__ import annotations

from pathlib import Path

from envs.errors import BenchError

__all__ = ["PUBLISHED_ROOT", "check_tuning_seeds", "published_seeds", "tuning_seeds"]

# The committed reproduction of a source checkout (absent from an installed package: no check).
PUBLISHED_ROOT = Path(__file__).resolve().parents[1] / "reproduction"


def published_seeds(root: Path | None = PUBLISHED_ROOT) -> dict[int, str]:
    """Seed -> the first committed grid under ``root`` that evaluates it ({} without ``root``)."""
    if root is None or not root.is_dir():
        return {}
    import pandas as pd

    from bench.design.grid_files import load_grid_file

    out: dict[int, str] = {}
    for store in sorted(root.glob("*/cells.parquet")):
        for seed in sorted(set(pd.read_parquet(store, columns=["seed"])["seed"].tolist())):
            out.setdefault(int(seed), _shown(store.parent, root))
    for grid in sorted([*root.glob("*.toml"), *root.glob("*.yaml"), *root.glob("*.yml")]):
        for cell in load_grid_file(grid).cells:
            out.setdefault(int(cell.seed), _shown(grid, root))
    return out


def _shown(path: Path, root: Path) -> str:
    """``path`` as ``reproduction/...`` (relative to the folder above ``root``)."""
    return str(path.relative_to(root.parent))


def tuning_seeds(study_seed: int, replicates: int) -> dict[str, int]:
    """Every seed a study uses: its evaluation seed and one training seed per replicate."""
    from studies.objective import eval_seed
    from studies.schedule import replicate_seed

    seeds = {"evaluation seed": eval_seed(study_seed)}
    seeds.update({f"training seed of replicate {r}": replicate_seed(study_seed, r) for r in range(replicates)})
    return seeds


def check_tuning_seeds(study_seed: int, replicates: int, published: dict[int, str]) -> None:
    """BenchError naming the first seed of the study that a published grid evaluates."""
    for what, seed in tuning_seeds(study_seed, replicates).items():
        if seed in published:
            raise BenchError(
                f"study seed {study_seed}: its {what} ({seed}) is a seed the published grid "
                f"{published[seed]} evaluates; tuning seeds must be disjoint from it (pick another --seed)")
