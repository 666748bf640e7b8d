"""The ``bench`` command line (SPEC 4 "CLI").

Every user mistake (unknown grid or method, bad value, unreachable --address, unwritable
--out, incompatible or corrupt results) prints ONE line on stderr and exits with status 2;
nothing already stored is changed. Heavy imports (torch, ray, reports) happen inside the
commands so ``bench --help`` is fast.
"""
from __future__ import annotations

import json
import math
import sys
from enum import Enum
from pathlib import Path
from typing import Any

import typer

try:  # typer >= 0.26 vendors click
    from typer._click import exceptions as click_exc
except ImportError:  # pragma: no cover - older typer on click
    from click import exceptions as click_exc

from envs.errors import BenchError

app = typer.Typer(
    name="bench", add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
    help="Warehouse MARL benchmark: run grids of cells on Ray, evaluate, report, profile.",
)


class GridName(str, Enum):
    smoke = "smoke"
    paper = "paper"
    full = "full"


class Suite(str, Enum):
    env = "env"
    hierarchical = "hierarchical"
    baselines = "baselines"
    pibt = "pibt"
    train = "train"
    all = "all"


def _version(value: bool) -> None:
    if value:
        from bench.about import git_commit, package_version

        typer.echo(f"warehouse-marl-bench {package_version()} (git {git_commit()})")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                 help="Print the package version and git commit, then exit."),
) -> None:
    """Warehouse MARL benchmark: run grids of cells on Ray, evaluate, report, profile."""


# --------------------------------------------------------------------- run
@app.command()
def run(
    grid: GridName | None = typer.Option(None, "--grid", help="Built-in grid: smoke (CI), paper (Fig. 1-3, Table I), full."),
    grid_file: Path | None = typer.Option(None, "--grid-file", help="User grid (TOML or YAML): a base cell and list-valued axes."),
    seeds: int | None = typer.Option(None, "--seeds", min=1, help="Replicate every configuration over seeds 0..K-1."),
    out: Path | None = typer.Option(None, "--out", help="Run directory (default: results/<grid>)."),
    address: str | None = typer.Option(None, "--address", help="Join a Ray cluster at host:port (or RAY_ADDRESS); default: embedded Ray."),
    workers: int | None = typer.Option(None, "--workers", min=1, help="Worker actors (one core each) (default: all CPUs)."),
    fresh: bool = typer.Option(False, "--fresh", help="Delete this run directory's results and start over (asks first)."),
    yes: bool = typer.Option(False, "--yes", "-y", help="Do not ask before --fresh deletes results."),
    checkpoint_every: int = typer.Option(10, "--checkpoint-every", min=1, help="Training iterations between checkpoints."),
) -> None:
    """Run (or resume) a grid: rerunning the same command skips finished cells and resumes
    interrupted ones from their last checkpoint."""
    from bench.grid_files import load_grid_file
    from bench.grids import get_grid
    from bench.store import RunStore

    if (grid is None) == (grid_file is None):
        raise BenchError("give exactly one of --grid {smoke,paper,full} or --grid-file PATH")
    g = get_grid(grid.value, seeds) if grid is not None else load_grid_file(grid_file, seeds)
    out_dir = out if out is not None else Path("results") / g.name
    store = RunStore(out_dir)
    store.check_writable()
    if fresh and store.exists() and not yes:
        if not sys.stdin.isatty():
            raise BenchError(f"--fresh would delete the results in {str(out_dir)!r}; pass --yes to confirm")
        if not typer.confirm(f"Delete every result in {out_dir} and start over?", default=False):
            raise typer.Abort()
    from bench.progress import make_progress
    from bench.runner import run_grid

    summary = run_grid(g, out_dir, address=address, workers=workers, fresh=fresh,
                       checkpoint_every=checkpoint_every, progress=make_progress(), command=sys.argv)
    typer.echo(f"{summary.done}/{summary.total} cells done, {summary.failed} failed, "
               f"{summary.wall_s:.1f} s -> {summary.out}")
    for cid, err in summary.failures.items():
        typer.echo(f"failed {cid}: {err}", err=True)
    if summary.failed:
        raise typer.Exit(1)


# ------------------------------------------------------------------- grids
@app.command()
def grids(
    seeds: int | None = typer.Option(None, "--seeds", min=1, help="Count with K seeds instead of each grid's default."),
    grid_file: Path | None = typer.Option(None, "--grid-file", help="Also list a user grid file."),
) -> None:
    """List the grids with their cell counts and estimated cost (cell-hours on one core)."""
    from rich.console import Console
    from rich.table import Table

    from bench import costs
    from bench.grid_files import load_grid_file
    from bench.grids import BUILTIN, get_grid

    table = Table(title=f"grids (cost: {costs.LABEL}, (episodes+eval)*horizon*N / agent-steps per s)")
    for col in ("grid", "cells", "methods", "N", "p", "seeds", "cell-hours"):
        table.add_column(col)
    listed = [get_grid(name, seeds) for name in BUILTIN]
    if grid_file is not None:
        listed.append(load_grid_file(grid_file, seeds))
    for g in listed:
        ns = sorted({c.n_robots for c in g.cells})
        ps = sorted({c.loss_p for c in g.cells})
        table.add_row(g.name, str(len(g)), ",".join(g.methods), ",".join(map(str, ns)),
                      ",".join(map(str, ps)), str(len({c.seed for c in g.cells})),
                      f"{costs.grid_cell_hours(g.cells):.3g}")
    console = Console(width=None if sys.stdout.isatty() else 140)  # logs: no truncated cells
    console.print(table)
    for g in listed:
        console.print(f"  {g.name}: {g.description}")


# -------------------------------------------------------------------- eval
@app.command("eval")
def eval_(
    method: str | None = typer.Option(None, "--method", help="Method name (hierarchical, decentralized, ic3net, pibt)."),
    checkpoint: Path | None = typer.Option(None, "--checkpoint", help="checkpoints/<cell_id>.pt of a run (default: untrained)."),
    n_robots: int | None = typer.Option(None, "--n-robots", min=1, help="Team size N (default: the checkpoint's, else 20)."),
    loss_p: float | None = typer.Option(None, "--loss-p", min=0.0, max=1.0, help="Loss probability p (default: the checkpoint's, else 0.2)."),
    layout: str | None = typer.Option(None, "--layout", help="Preset name or .map path (default: preset sized for N)."),
    episodes: int = typer.Option(10, "--episodes", min=1, help="Evaluation episodes."),
    seed: int | None = typer.Option(None, "--seed", min=0, help="Seed (default: the checkpoint's, else 0)."),
    horizon: int | None = typer.Option(None, "--horizon", min=1, help="Horizon T (default: the checkpoint's, else 500)."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON (mean metrics and every episode) instead of a table."),
) -> None:
    """Evaluate one method (its own execution mode: argmax or sampled); print the eval metrics."""
    from bench.quick_eval import quick_eval, summarize

    cell, rows = quick_eval(method, str(checkpoint) if checkpoint else None, n_robots, loss_p, layout,
                            episodes, seed, horizon)
    means = summarize(rows)
    if as_json:
        typer.echo(json.dumps({"cell": json.loads(cell.canonical_json()), "checkpoint": str(checkpoint or ""),
                               "mean": _jsonable(means), "episodes": [_jsonable(r) for r in rows]}, indent=2))
        return
    from rich.console import Console
    from rich.table import Table

    src = f"checkpoint {checkpoint}" if checkpoint else "untrained initialization"
    table = Table(title=f"{cell.method} N={cell.n_robots} p={cell.loss_p} layout={cell.layout} "
                        f"seed={cell.seed}, {len(rows)} episodes, {src}")
    table.add_column("metric")
    table.add_column("mean", justify="right")
    for k, v in means.items():
        table.add_row(k, "nan" if math.isnan(v) else f"{v:.4g}")
    Console().print(table)


def _jsonable(d: dict[str, Any]) -> dict[str, Any]:
    return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in d.items()}


# ---------------------------------------------------------- report / replay
def _run_dir(run: Path | None) -> Path:
    from bench.store import RunStore

    if run is None:
        found = sorted(Path("results").glob("*/manifest.json"), key=lambda p: p.stat().st_mtime)
        if not found:
            raise BenchError("no run found under results/; pass --run DIR")
        run = found[-1].parent
    RunStore(run).require_run()
    return run


@app.command()
def report(
    run: Path | None = typer.Option(None, "--run", help="Run directory (default: the most recent under results/)."),
) -> None:
    """Rebuild every figure and table of a run from its Parquet store into RUN/report/."""
    run_dir = _run_dir(run)
    try:
        from reports.build import build_report
    except ImportError as exc:
        raise BenchError(f"the report builder is not available: {exc}") from None
    out = build_report(run_dir)
    typer.echo(f"report: {out / 'index.html'}  (also index.md, figures, tables, claims.md)")


@app.command()
def replay(
    run: Path = typer.Option(..., "--run", help="Run directory."),
    cell: str = typer.Option(..., "--cell", help="cell_id (see cells.parquet)."),
    episode: int = typer.Option(0, "--episode", min=0, help="Evaluation episode to replay."),
    out: Path | None = typer.Option(None, "--out", help="Output GIF path (default: RUN/replays/<cell>-ep<K>.gif)."),
) -> None:
    """Render one evaluation episode of a cell as a GIF."""
    from bench.store import RunStore

    run_dir = _run_dir(run)
    cells = RunStore(run_dir).read_cells()
    if cells is None or cell not in set(cells["cell_id"]):
        raise BenchError(f"cell {cell!r} is not in {str(run_dir / 'cells.parquet')!r}")
    try:
        from reports.replay import write_replay
    except ImportError as exc:
        raise BenchError(f"the replay writer is not available: {exc}") from None
    target = out if out is not None else run_dir / "replays" / f"{cell}-ep{episode}.gif"
    typer.echo(str(write_replay(run_dir, cell, episode, target)))


# -------------------------------------------------------------------- perf
PERF_SUITES = {
    "env": ("bench.perf_env", "run_env_suite"),
    "hierarchical": ("bench.perf_methods", "run_hierarchical_suite"),
    "baselines": ("bench.perf_baselines", "run_baselines_suite"),
    "pibt": ("bench.perf_pibt", "run_pibt_suite"),
    "train": ("bench.perf_methods", "run_train_suite"),  # env-steps/s per cell, N = 40 and 100
}


@app.command()
def perf(
    suite: Suite = typer.Option(Suite.all, "--suite", help="Which benchmark suite to run."),
    json_path: Path | None = typer.Option(None, "--json", help="Also write the results as JSON records."),
) -> None:
    """Measure throughput of the hot loops (environment, methods, planner)."""
    import importlib

    import pandas as pd

    names = list(PERF_SUITES) if suite is Suite.all else [suite.value]
    frames = []
    for name in names:
        module, func = PERF_SUITES[name]
        try:
            fn = getattr(importlib.import_module(module), func)
        except (ImportError, AttributeError) as exc:
            if suite is not Suite.all:
                raise BenchError(f"perf suite {name!r} is not available: {exc}") from None
            typer.echo(f"bench perf: skipping suite {name!r} (not available: {exc})", err=True)
            continue
        frames.append(fn())
    df = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    _print_frame(df, f"bench perf --suite {suite.value}")
    if json_path is not None:
        from bench.store import atomic_file

        with atomic_file(json_path) as fh:
            fh.write(df.to_json(orient="records", indent=2).encode())


def _print_frame(df: Any, title: str) -> None:
    """Plain aligned text (wide tables stay readable in logs and narrow terminals)."""
    typer.echo(title)
    typer.echo(df.to_string(index=False, float_format=lambda v: f"{v:.4g}") if len(df) else "(no rows)")


# -------------------------------------------------------------------- tune
def _register_tune() -> None:
    from studies.cli import tune  # light: optuna, ray and torch load inside the command

    app.command("tune")(tune)


_register_tune()


# -------------------------------------------------------------------- main
def _error(msg: str) -> None:
    text = " ".join(str(msg).split()).replace("Value error, ", "")
    print(f"bench: error: {text}", file=sys.stderr)


def main(argv: list[str] | None = None) -> None:
    """Console entry point: one-line errors with exit status 2 for user mistakes."""
    try:
        code = app(args=argv, prog_name="bench", standalone_mode=False)
    except BenchError as exc:
        _error(str(exc))
        sys.exit(2)
    except click_exc.NoArgsIsHelpError as exc:
        print(exc.format_message())
        sys.exit(0)
    except click_exc.UsageError as exc:
        _error(exc.format_message())
        sys.exit(2)
    except click_exc.ClickException as exc:
        _error(exc.format_message())
        sys.exit(exc.exit_code)
    except (typer.Abort, EOFError):
        _error("aborted; nothing was changed")
        sys.exit(1)
    except KeyboardInterrupt:
        _error("interrupted; rerun the same command to resume")
        sys.exit(130)
    if code == 130:  # Ctrl-C (typer turns KeyboardInterrupt into exit status 130)
        _error("interrupted; rerun the same command to resume")
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":
    main()
