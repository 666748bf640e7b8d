"""Named grids of cells: ``smoke`` (CI), ``paper`` (Fig. 1-3, Table I), ``full`` (SPEC 4),
``ablation`` (the hierarchical method's components, issue 18), ``lifelong`` (CI: lifelong
tasks with and without message delay).

A grid is a deduplicated, ordered tuple of cells. ``--seeds K`` replicates every
configuration over seeds 0..K-1; ``paper`` runs 3 seeds by default (the fewest a claim's
verdict accepts; ``--seeds 5`` where compute allows), ``full`` 3, ``smoke`` 1. User grids come from TOML/YAML files
(bench/design/grid_files.py).
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from algorithms.registry import method_class
from bench.design.cells import Cell
from bench.design.paper import (
    PAPER_FIG1_P,
    PAPER_FIG1A_N,
    PAPER_FIG1B_N,
    PAPER_FIG2_N,
    PAPER_FIG2_P,
    PAPER_FIG3_P,
    PAPER_N,
    PAPER_P,
    PAPER_SETTINGS,
    PAPER_TABLE1_N,
    PAPER_TABLE1_P,
)
from envs.errors import BenchError

ALL_METHODS = ("hierarchical", "decentralized", "ic3net", "pibt")


@dataclass(frozen=True)
class Grid:
    name: str
    description: str
    cells: tuple[Cell, ...]

    def __len__(self) -> int:
        return len(self.cells)

    @property
    def methods(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(c.method for c in self.cells))

    @property
    def seeds(self) -> int:
        """Distinct seeds of the grid."""
        return len({c.seed for c in self.cells})

    @property
    def configurations(self) -> int:
        """Distinct cells once the seed is ignored (each runs ``seeds`` times)."""
        return len({c.model_copy(update={"seed": 0}).canonical_json() for c in self.cells})


def dedup(cells: Iterable[Cell]) -> tuple[Cell, ...]:
    """Cells in first-seen order, each cell_id once."""
    return tuple({c.cell_id: c for c in cells}.values())


def _cells(specs: Iterable[dict[str, Any]], seeds: int) -> tuple[Cell, ...]:
    return dedup(Cell.make(**spec, seed=s) for spec in specs for s in range(seeds))


def _planner_settings(spec: dict[str, Any]) -> dict[str, Any]:
    """A planner (``Method.learned`` False, e.g. PIBT) learns nothing: no training episodes."""
    return spec if method_class(spec["method"]).learned else {**spec, "episodes": 0}


def smoke(seeds: int = 1) -> Grid:
    """Every method at N in {8 (tiny), 16 (wh20)} x p in {0.2, 0.6}; tiny budgets (CI)."""
    specs = [
        _planner_settings(dict(
            method=m, n_robots=n, layout=layout, loss_p=p, episodes=16, horizon=48,
            eval_episodes=10, params={"batch_episodes": 8, "eval_chunk": 5},
        ))
        for m in ALL_METHODS for n, layout in ((8, "tiny"), (16, "wh20")) for p in (0.2, 0.6)
    ]
    return Grid("smoke", "CI: every method, N in {8,16}, p in {0.2,0.6}, tiny budgets",
                _cells(specs, seeds))


def lifelong(seeds: int = 1) -> Grid:
    """Lifelong tasks (beyond the paper): every method at N=8 (tiny), p=0.2, with no delay
    and a fixed 2-step delay; smoke budgets (CI runs it end to end)."""
    specs = [
        _planner_settings(dict(
            method=m, n_robots=8, layout="tiny", loss_p=0.2, task="lifelong", delay=d, episodes=16,
            horizon=48, eval_episodes=10, params={"batch_episodes": 8, "eval_chunk": 5},
        ))
        for m in ALL_METHODS for d in (0, 2)
    ]
    return Grid("lifelong", "CI: every method, lifelong tasks, N=8, p=0.2, delay 0 and 2, tiny budgets",
                _cells(specs, seeds))


def paper_specs() -> list[dict[str, Any]]:
    """(method, N, p) behind the paper's figures and table, in figure order (duplicates kept)."""
    out: list[tuple[str, int, float]] = []
    # Fig. 1(a): hierarchical vs decentralized at N=20,40,60; Fig. 1(b): hierarchical 80..100.
    out += [(m, n, PAPER_FIG1_P) for n in PAPER_FIG1A_N for m in ("hierarchical", "decentralized")]
    out += [("hierarchical", n, PAPER_FIG1_P) for n in PAPER_FIG1B_N]
    # Fig. 2: hierarchical vs IC3Net at N=40,60 and every p.
    out += [(m, n, p) for n in PAPER_FIG2_N for p in PAPER_FIG2_P for m in ("hierarchical", "ic3net")]
    # Fig. 3: payload of hierarchical vs decentralized over every N at p=0.2.
    out += [(m, n, PAPER_FIG3_P) for n in PAPER_N for m in ("hierarchical", "decentralized")]
    # Table I: safety filter of hierarchical at N=40..100, p=0.2.
    out += [("hierarchical", n, PAPER_TABLE1_P) for n in PAPER_TABLE1_N]
    # Beyond the paper: PIBT as a planner reference at the same N (full information).
    out += [("pibt", n, PAPER_TABLE1_P) for n in PAPER_N]
    return [_planner_settings(dict(method=m, n_robots=n, loss_p=p, **PAPER_SETTINGS)) for m, n, p in out]


def paper(seeds: int = 3) -> Grid:
    """Exactly the configurations of Fig. 1, Fig. 2, Fig. 3 and Table I, plus PIBT."""
    return Grid("paper", "Fig. 1-3 and Table I of the paper (+ PIBT reference), paper budgets",
                _cells(paper_specs(), seeds))


def full(seeds: int = 3) -> Grid:
    """Every method x N in {20..100} x p in {0.2, 0.4, 0.6} x seeds, paper budgets."""
    specs = [
        _planner_settings(dict(method=m, n_robots=n, loss_p=p, **PAPER_SETTINGS))
        for m in ALL_METHODS for n in PAPER_N for p in PAPER_P
    ]
    return Grid("full", "every method x N in {20..100} x p in {0.2,0.4,0.6}, paper budgets",
                _cells(specs, seeds))


@dataclass(frozen=True)
class Variant:
    """One arm of the ablation: a method with hyperparameter overrides and the paper line
    it departs from (docs/decisions/0118)."""

    label: str
    method: str
    params: dict[str, Any]
    departs: str
    ref_size: int = 8


# Issue 18: the hierarchical method's design choices, one at a time, and the baseline.
ABLATION_VARIANTS = (
    Variant("paper", "hierarchical", {}, "none (the paper's method, defaults of docs/decisions.md)"),
    Variant("shared parameters", "hierarchical", {"share_params": True},
            "Sec. II: psi_z, theta_z, eta_z per group -> one set for all groups"),
    Variant("per-robot fallback", "hierarchical", {"fallback": "per_robot"},
            "alg:safety_filter line 12: joint Wait -> only offending robots wait"),
    Variant("resample on fallback", "hierarchical", {"resample_on_fallback": True},
            "eq:local_deterministic_control: argmax execution -> a fallen-back group samples once from pi"),
    Variant("no reference", "hierarchical", {}, "eq:reference_policy: |R_z| = 1 (r carries nothing)",
            ref_size=1),
    Variant("oracle messages", "hierarchical", {"messages": "oracle"},
            "eq:interaction_state_estimate: ground truth on lost links (predictor upper bound)"),
    Variant("last-received messages", "hierarchical", {"messages": "last"},
            "eq:recurrent_predictor: no GRU, the last received message on lost links"),
    Variant("held reference", "hierarchical", {"ref_hold": 10, "ref_entropy_coef": 0.0},
            "eq:reference_policy: r drawn every step -> held 10 steps, no entropy bonus on mu"),
    Variant("decentralized", "decentralized", {}, "the baseline of Sec. IV (no hierarchy, no filter)"),
)
# The paper's Z, L, C_max, evaluation budget and layout at N = 40, p = 0.2; shorter training.
ABLATION_SETTINGS: dict[str, Any] = dict(
    PAPER_SETTINGS, n_robots=40, loss_p=0.2, episodes=1000, horizon=300,
)


def ablation_specs(**overrides: Any) -> list[dict[str, Any]]:
    """One cell spec per ablation variant; ``overrides`` replace ``ABLATION_SETTINGS``
    (a ``params`` override is merged under each variant's own params)."""
    base = {**ABLATION_SETTINGS, **overrides}
    common = base.pop("params", {})
    return [dict(base, method=v.method, ref_size=v.ref_size, params={**common, **v.params})
            for v in ABLATION_VARIANTS]


def ablation(seeds: int = 3) -> Grid:
    """The hierarchical method's components one at a time at N=40, p=0.2 on the MovingAI
    map (1000 episodes of 300 steps), and the decentralized baseline (issue 18)."""
    return Grid("ablation", "hierarchical variants + decentralized, N=40, p=0.2, MovingAI map, "
                "1000 episodes x 300 steps", _cells(ablation_specs(), seeds))


BUILTIN: dict[str, Callable[..., Grid]] = {"smoke": smoke, "paper": paper, "full": full, "ablation": ablation,
                                           "lifelong": lifelong}
DEFAULT_SEEDS = {"smoke": 1, "paper": 3, "full": 3, "ablation": 3, "lifelong": 1}


def get_grid(name: str, seeds: int | None = None) -> Grid:
    """A built-in grid by name; ``seeds`` replaces its default seed count."""
    if name not in BUILTIN:
        raise BenchError(f"unknown grid {name!r}; choose one of {', '.join(BUILTIN)} or pass --grid-file")
    if seeds is not None and seeds < 1:
        raise BenchError(f"--seeds must be >= 1, got {seeds}")
    from bench.design.limits import check_count

    check_count("--seeds", "seeds", seeds)
    return BUILTIN[name](seeds if seeds is not None else DEFAULT_SEEDS[name])
