"""The ``bench`` command line (SPEC 4 "CLI").

Every user mistake (unknown grid or method, bad value, unreachable --address, unwritable
--out, incompatible or corrupt results) prints ONE line on stderr and exits with status 2;
nothing already stored is changed. Heavy imports (torch, ray, reports) happen inside the
commands so ``bench --help`` is fast.
"""
from __future__ import annotations

import json
import math
import os
import sys
from enum import Enum
from pathlib import Path
from typing import Any

import typer

try:  # typer >= 0.26 vendors click
    from typer._click import exceptions as click_exc
except ImportError:  # pragma: no cover - older typer on click
    from click import exceptions as click_exc  # type: ignore[no-redef]  # the same module, unvendored

from envs.errors import BenchError

__all__ = ["app", "main"]

# The `bench` command and its subcommands (`main` runs it with the bench's error handling).
app = typer.Typer(
    name="bench", add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
    rich_markup_mode=None,  # plain click help: flags show no "<bool>" value (typer 0.29's rich help does)
    help="Warehouse MARL benchmark: run grids of cells on Ray, evaluate, report, profile.",
)


class Suite(str, Enum):
    env = "env"
    hierarchical = "hierarchical"
    baselines = "baselines"
    pibt = "pibt"
    train = "train"
    peers = "peers"
    cli = "cli"
    protocol = "protocol"
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
    grid: str | None = typer.Option(None, "--grid",
        help="Named grid (`bench grids` lists them): smoke (CI), paper (Fig. 1-3, Table I), full, ablation "
             "(hierarchical variants), or one an installed package registers."),
    grid_file: Path | None = typer.Option(None, "--grid-file",
        help="User grid (TOML or YAML): a base cell and list-valued axes."),
    seeds: int | None = typer.Option(None, "--seeds", min=1,
        help="Replicate every configuration over seeds 0..K-1 (default: paper 3, full 3, smoke 1; a verdict needs 3)."),
    out: Path | None = typer.Option(None, "--out", help="Run directory (default: results/<grid>)."),
    address: str | None = typer.Option(None, "--address",
        help="Join a Ray cluster at host:port (or RAY_ADDRESS); default: embedded Ray."),
    workers: int | None = typer.Option(None, "--workers", min=1,
        help="Worker actors (one core each) (default: all CPUs)."),
    fresh: bool = typer.Option(False, "--fresh",
        help="Delete the files the bench wrote in this run directory and start over (asks first; other files stay; a "
             "folder without manifest.json is refused)."),
    yes: bool = typer.Option(False, "--yes", "-y", help="Do not ask before --fresh deletes results."),
    checkpoint_every: int = typer.Option(10, "--checkpoint-every", min=1,
        help="Training iterations between checkpoints."),
    rerun_changed: bool = typer.Option(False, "--rerun-changed",
        help="Train again, from the start, the stored cells whose resolved method parameters differ from this code's "
             "(a default changed); their old files move to RUN/superseded/. Without it such a run is refused."),
    stack_seeds: str = typer.Option("auto", "--stack-seeds", metavar="auto|K",
        help="Train up to K cells that differ only in their seed in one worker, their rollouts as one batch (the "
             "learned methods; the same numbers as one by one; the hierarchical method "
             "about 1.1-1.5x less CPU per cell). auto (default): the W longest cells (W = workers) run first, each "
             "alone (the critical path), and the other hierarchical cells in stacks of 3 when there are more of "
             "them than workers; 1: no stacking. A resumed run may stack differently."),
    repair: bool = typer.Option(False, "--repair",
        help="Move every damaged or misplaced stored file of the grid's cells (checksum mismatch, unreadable, rows of "
             "another cell) to RUN/superseded/repair-<time>/ and recompute those cells only. Without it such a run is "
             "refused, naming the file."),
    log: str | None = typer.Option(None, "--log",
        help="Experiment tracking, comma-separated: tensorboard, mlflow, wandb (offline). Per-update training metrics "
             "and each cell's evaluation summary, one tracker run per cell named by its id, under RUN/tracking/ "
             "(needs the track extra). Default: none."),
    verbose: bool = typer.Option(False, "--verbose", "-v",
        help="Without a terminal, log every event (cell started, each training chunk and evaluation unit) instead of "
             "one line per finished or failed cell and a summary every 5 minutes."),
    set_: list[str] | None = typer.Option(None, "--set",
        help="Override a cell field in every cell of the grid, KEY=VALUE (repeatable; e.g. horizon=32, "
             "params.lr=0.01). Recorded in manifest.json; a resumed run must give the same overrides."),
    axis: list[str] | None = typer.Option(None, "--axis",
        help="Cross every cell with each value, KEY=V1,V2 (repeatable; e.g. loss_p=0.1,0.3)."),
    device: str | None = typer.Option(None, "--device",
        help="Torch device of the learned methods' networks, optimizers and update tensors: cpu (default) or cuda, "
             "cuda:N (the environment, observations and safety filter stay on the host; numbers differ from the "
             "cpu's in float rounding). Not part of a cell: recorded in the manifest (docs/guide/speed.md)."),
    cell_threads: str = typer.Option("1", "--cell-threads", metavar="K",
        help="Torch threads per cell (default 1), each worker taking K CPUs: for an idle machine with more cores than "
             "cells. More than 1 changes the numbers in float rounding (deterministic for a given K, not those of "
             "1 thread), forms no seed stacks, and is recorded in each cell's checkpoint and eval file; a resumed "
             "cell keeps the count it started with (docs/guide/speed.md)."),
) -> None:
    """Run (or resume) a grid: rerunning the same command skips finished cells and resumes
    interrupted ones from their last checkpoint. Ctrl-C or SIGTERM keeps every checkpoint."""
    from algorithms.common.device import check_device
    from bench.tracking import parse_log

    device = check_device(device)  # a bad or absent device: one line, before any grid is built
    threads = _cell_threads(cell_threads)

    log_names = parse_log(log)
    from bench.design.overrides import apply_overrides, parse_overrides

    overrides = parse_overrides(set_ or (), axis or ())  # a misspelled key: one line before any grid is built
    from bench.design.grid_files import check_run_name, load_grid_file
    from bench.design.grids import get_grid
    from bench.execute.runner import sigterm_as_interrupt, sigterm_received
    from bench.store.run_store import RunStore

    if (grid is None) == (grid_file is None):
        raise BenchError("give exactly one of --grid {smoke,paper,full,ablation} or --grid-file PATH")
    from bench.design.limits import check_count

    stacking = _stack_seeds(stack_seeds)
    for option, field, value in (("--workers", "workers", workers),
                                 ("--checkpoint-every", "checkpoint_every", checkpoint_every),
                                 ("--stack-seeds", "stack_seeds", stacking if isinstance(stacking, int) else None)):
        check_count(option, field, value)
    if grid is not None:
        g = get_grid(grid, seeds)
    else:
        assert grid_file is not None  # exactly one of the two, checked above
        g = load_grid_file(grid_file, seeds)
    g = apply_overrides(g, overrides)
    out_dir = out if out is not None else Path("results") / check_run_name(g.name, "grid name")
    store = RunStore(out_dir)
    store.check_writable(repair and not fresh)
    if fresh:
        store.check_fresh()
        n_files = len(store.bench_files())
        if n_files and not yes:
            if not sys.stdin.isatty():
                raise BenchError(f"--fresh would delete the {n_files} files the bench wrote in "
                                 f"{str(out_dir)!r}; pass --yes to confirm")
            if not typer.confirm(f"Delete the {n_files} files the bench wrote in {out_dir} (other files "
                                 "stay) and start over?", default=False):
                raise typer.Abort()
    from bench.execute.progress import make_progress
    from bench.execute.runner import run_grid
    from bench.tracking import make_observer

    observer = make_observer(log_names, out_dir, g.name)
    try:
        with sigterm_as_interrupt():
            summary = run_grid(g, out_dir, address=address, workers=workers, fresh=fresh,
                               checkpoint_every=checkpoint_every, progress=make_progress(verbose),
                               command=sys.argv, rerun_changed=rerun_changed, stack_seeds=stacking,
                               repair=repair, observer=observer, overrides=overrides, device=device,
                               cell_threads=threads)
    except KeyboardInterrupt:
        if sigterm_received():
            raise typer.Exit(143) from None
        raise
    finally:
        if observer is not None:
            observer.close()
    for line in summary.repaired:
        typer.echo(f"bench: repair: {line}", err=True)
    for cid, why in summary.rerun.items():
        typer.echo(f"bench: warning: cell {cid} {why}", err=True)
    typer.echo(f"{summary.done}/{summary.total} cells done, {summary.failed} failed, "
               f"{summary.wall_s:.1f} s -> {summary.out}")
    for cid, err in summary.failures.items():
        typer.echo(f"failed {cid}: {err}", err=True)
    if summary.failed:
        raise typer.Exit(1)


def _stack_seeds(text: str) -> int | str:
    """``--stack-seeds``: auto or a count; a bad value is one BenchError line."""
    from bench.design.costs import parse_stack_seeds

    try:
        return parse_stack_seeds(text)
    except ValueError as exc:
        raise BenchError(str(exc)) from None


def _cell_threads(text: str) -> int:
    """``--cell-threads``: a count; a bad value is one BenchError line."""
    from bench.execute.torch_setup import parse_cell_threads

    try:
        return parse_cell_threads(text)
    except ValueError as exc:
        raise BenchError(str(exc)) from None


# ------------------------------------------------------------------- grids
@app.command()
def grids(
    seeds: int | None = typer.Option(None, "--seeds", min=1, help="Count with K seeds instead of each grid's default."),
    grid_file: Path | None = typer.Option(None, "--grid-file", help="Also list a user grid file."),
    stack_seeds: str = typer.Option("1", "--stack-seeds", metavar="auto|K",
                                    help="Estimate for `bench run --stack-seeds K` (seed-stacked training: its "
                                    "measured per-cell gain); auto: bench run's default with one worker per CPU "
                                    "of this machine."),
    rates_from: Path | None = typer.Option(None, "--rates-from", help="Estimate with the rates a run directory's "
                                           "done cells observed (your machine), where it has them; the "
                                           "built-in rates elsewhere."),
    rates_stack_seeds: int = typer.Option(1, "--rates-stack-seeds", min=1, help="The --stack-seeds the "
                                          "--rates-from run was made with: its seed-stacked cells' training "
                                          "rates are scaled back to one seed."),
) -> None:
    """List the grids with their cell counts (configurations x seeds) and cost (worker-hours,
    every seed and every evaluation mode counted; rates observed on the committed
    reproduction's cells unless --rates-from)."""
    from rich.console import Console
    from rich.table import Table

    from bench.design import costs
    from bench.design.grid_files import load_grid_file
    from bench.design.grids import get_grid, grid_builders

    stacking = _stack_seeds(stack_seeds)
    workers = os.cpu_count() or 1
    rates = None
    source = f"{costs.LABEL} on {costs.RATES_RUN}"
    if rates_from is None and rates_stack_seeds > 1:
        raise BenchError("--rates-stack-seeds: it describes the --rates-from run, and none is given")
    if rates_from is not None:
        if not (rates_from / "cells.parquet").is_file():
            raise BenchError(f"--rates-from {str(rates_from)!r}: no results store there (cells.parquet not found)")
        from bench.design.cost_calibration import merged_rates, observed_costs, observed_rates  # pandas

        observed = observed_costs(rates_from, rates_stack_seeds)
        if observed.empty:
            raise BenchError(f"--rates-from {str(rates_from)!r}: the run has no done cell to take rates from")
        rates = merged_rates(observed_rates(observed))
        stacked_run = f" (made with --stack-seeds {rates_stack_seeds})" if rates_stack_seeds > 1 else ""
        source = f"rates of the {len(observed)} done cells of {rates_from}{stacked_run}, built-in elsewhere"
    stacked = (f", --stack-seeds auto with {workers} workers" if stacking == costs.AUTO else
               f", --stack-seeds {stacking}" if stacking != 1 else "")
    table = Table(title=f"grids (cost: (episodes + eval episodes x modes) x horizon x N / agent-steps per s, "
                        f"{source}{stacked}; summed over cells = configurations x seeds)")
    for col in ("grid", "cells", "methods", "N", "p", "configs", "seeds", "worker-hours"):
        table.add_column(col)
    listed = [get_grid(name, seeds) for name in grid_builders()]
    if grid_file is not None:
        listed.append(load_grid_file(grid_file, seeds))
    for g in listed:
        ns = sorted({c.n_robots for c in g.cells})
        ps = sorted({c.loss_p for c in g.cells})
        table.add_row(g.name, str(len(g)), ",".join(g.methods), ",".join(map(str, ns)),
                      ",".join(map(str, ps)), str(g.configurations), str(g.seeds),
                      f"{costs.grid_cell_hours(g.cells, rates, stacking, workers):.3g}")
    console = Console(width=None if sys.stdout.isatty() else 140)  # logs: no truncated cells
    console.print(table)
    for g in listed:
        console.print(f"  {g.name}: {g.description}")


# ----------------------------------------------------------------- methods
@app.command()
def methods(
    method: str | None = typer.Argument(None, help="One method (a registered name or module:Class): "
                                        "also list its hyperparameters with defaults."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table."),
) -> None:
    """List every method: where it comes from (built-in, entry point, module path), whether
    it learns, its execution modes, safety-filter default and payload model. A method is
    named in grid files, `bench eval --method` and `bench tune --method` by a registered
    name or as module:Class (docs/extending.md). A method that cannot be imported is one
    error line after the others (exit status 2)."""
    from algorithms.registry import available, describe

    names = [method] if method else list(available())
    info, broken = [], []
    for name in names:  # one plugin that does not import leaves the others listed (D13)
        try:
            info.append(describe(name))
        except BenchError as exc:
            if method:
                raise
            broken.append(str(exc))
    _methods_table(info, method, as_json)
    for line in broken:
        _error(line)
    if broken:
        raise typer.Exit(2)


def _methods_table(info: list[dict[str, Any]], method: str | None, as_json: bool) -> None:
    """What ``bench methods`` prints to stdout: JSON, or the table (and one method's parameters)."""
    from rich.console import Console
    from rich.table import Table

    if as_json:
        typer.echo(json.dumps(info, indent=2, default=str))
        return
    console = Console(width=None if sys.stdout.isatty() else 160)
    table = Table(title="methods (entry-point group warehouse_marl_bench.methods, or module:Class)")
    for col in ("name", "display name", "source", "learns", "executions", "safety filter", "payload"):
        table.add_column(col)
    for d in info:
        table.add_row(d["name"], d["display_name"], d["source"], "yes" if d["learned"] else "no (planner)",
                      d["executions"], "on" if d["safety_filter"] else "off", d["payload"])
    console.print(table)
    if method:
        params = Table(title=f"{method} hyperparameters ({info[0]['target']}; a cell's params override them)")
        for col in ("parameter", "default", "description"):
            params.add_column(col)
        for name, (default, text) in info[0]["params"].items():
            params.add_row(name, json.dumps(default), text)
        console.print(params)
        if info[0]["presets"]:
            presets = Table(title=f'{method} presets (a grid file selects one with preset = "NAME"; '
                                  '"paper" is the defaults above)')
            for col in ("preset", "values", "source"):
                presets.add_column(col)
            for name, p in info[0]["presets"].items():
                values = ", ".join(f"{k}={json.dumps(v)}" for k, v in p["values"].items())
                presets.add_row(name, values if p["published"] else "(no published study yet)", p["source"])
            console.print(presets)


# -------------------------------------------------------------------- eval
@app.command("eval")
def eval_(
    method: str | None = typer.Option(None, "--method",
        help="A registered method name or module:Class (`bench methods` lists them)."),
    checkpoint: Path | None = typer.Option(None, "--checkpoint",
        help="checkpoints/<method>-<cell_id>.pt of a run (default: untrained)."),
    n_robots: int | None = typer.Option(None, "--n-robots", min=1,
        help="Team size N (default: the checkpoint's, else 20)."),
    loss_p: float | None = typer.Option(None, "--loss-p", min=0.0, max=1.0,
        help="Loss probability p (default: the checkpoint's, else 0.2)."),
    layout: str | None = typer.Option(None, "--layout", help="Preset name or .map path (default: preset sized for N)."),
    episodes: int = typer.Option(10, "--episodes", min=1, help="Evaluation episodes."),
    seed: int | None = typer.Option(None, "--seed", min=0, help="Seed (default: the checkpoint's, else 0)."),
    horizon: int | None = typer.Option(None, "--horizon", min=1,
        help="Horizon T (default: the checkpoint's, else 500)."),
    as_json: bool = typer.Option(False, "--json",
        help="Print JSON (mean metrics per mode and every episode) instead of a table."),
    execution: str | None = typer.Option(None, "--execution",
        help="One execution mode: argmax, sample, sample@T (e.g. sample@0.5); planner for pibt (default: every mode "
             "of the cell)."),
    device: str | None = typer.Option(None, "--device",
        help="Torch device of the networks: cpu (default), cuda or cuda:N."),
    set_: list[str] | None = typer.Option(None, "--set",
        help="KEY=VALUE: a cell field or params.NAME set for this evaluation (repeatable), e.g. "
             "params.fallback=per_robot to evaluate a checkpoint under another fallback rule."),
) -> None:
    """Evaluate one method in every execution mode (argmax, sample, sample@0.5; planner for
    a planner) on the same scenarios; print the eval metrics, one column per mode."""
    from algorithms.common.device import check_device

    device = check_device(device)
    if method is not None:  # a misspelled name is one line before torch and Ray load
        from algorithms.registry import available, is_path, method_class

        if not is_path(method) and method not in available():
            method_class(method)  # the registry's one-line error, naming the registered methods
    from bench.design.overrides import parse_overrides
    from bench.execute.quick_eval import quick_eval, summarize

    overrides = parse_overrides(set_ or [])["set"]
    cell, rows = quick_eval(method, str(checkpoint) if checkpoint else None, n_robots, loss_p, layout,
                            episodes, seed, horizon, execution=execution, device=device, sets=overrides)
    means = summarize(rows)
    if as_json:
        typer.echo(json.dumps({"cell": json.loads(cell.canonical_json()), "checkpoint": str(checkpoint or ""),
                               "executions": list(means),
                               "mean": {m: _jsonable(v) for m, v in means.items()},
                               "episodes": [_jsonable(r) for r in rows]}, indent=2))
        return
    from rich.console import Console
    from rich.table import Table

    src = f"checkpoint {checkpoint}" if checkpoint else "untrained initialization"
    src += "".join(f", {k}={v}" for k, v in overrides.items())  # what --set changed
    per_mode = len(rows) // max(len(means), 1)
    table = Table(title=f"{cell.method} N={cell.n_robots} p={cell.loss_p} layout={cell.layout} "
                        f"seed={cell.seed}, {per_mode} episodes per mode (same scenarios), {src}")
    table.add_column("metric (mean)")
    for mode in means:
        table.add_column(mode, justify="right")
    for k in next(iter(means.values()), {}):
        table.add_row(k, *("nan" if math.isnan(v[k]) else f"{v[k]:.4g}" for v in means.values()))
    Console().print(table)


def _jsonable(d: dict[str, Any]) -> dict[str, Any]:
    return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in d.items()}


# ---------------------------------------------------------- report / replay
def _run_dir(run: Path | None) -> Path:
    from bench.store.run_store import RunStore

    if run is None:
        found = sorted(Path("results").glob("*/manifest.json"), key=lambda p: p.stat().st_mtime)
        if not found:
            raise BenchError("no run found under results/; pass --run DIR")
        run = found[-1].parent
    RunStore(run).require_run()
    return run


class ClaimsAt(str, Enum):
    paper = "paper"
    run = "run"


@app.command()
def report(
    run: Path | None = typer.Option(None, "--run", help="Run directory (default: the most recent under results/)."),
    out: Path | None = typer.Option(None, "--out",
        help="Write the report here instead of RUN/report/ (e.g. for a read-only run directory)."),
    claims_at: ClaimsAt = typer.Option(ClaimsAt.paper, "--claims-at",
        help="Check claims at the paper's configurations only, or also at the run's own."),
    against: Path | None = typer.Option(None, "--against", help="Also report the done cells of this run directory "
                                        "(e.g. reproduction/paper) at the configurations RUN covers, as if they had "
                                        "run together; refused unless settings and scenarios match."),
    force: bool = typer.Option(False, "--force",
        help="Write into an --out folder that holds files the bench did not write (default: refused)."),
) -> None:
    """Rebuild every figure and table of a run from its Parquet store into RUN/report/ (or --out).
    Warns naming every done cell whose stored rows are incomplete. With --against REF, a
    method of your own is judged against REF's committed baselines without retraining them."""
    import os

    from bench.store.outputs import check_report_out

    run_dir = _run_dir(run)
    target = out if out is not None else run_dir / "report"
    if out is not None:
        check_report_out(out, force)
    if out is None and not _writable(target):
        raise BenchError(f"run directory {str(run_dir)!r} is read-only; write the report elsewhere "
                         "with --out DIR")
    from bench.store.integrity import find_damage
    from bench.store.run_store import RunStore

    store = RunStore(run_dir)
    damage = find_damage(store, store.integrity())
    broken = [d for d in damage if d.rel == "cells.parquet"]
    if broken:
        raise BenchError(f"{str(run_dir)!r}: {broken[0].line()}")
    cells = store.read_cells()
    damaged = {d.cell_id for d in damage}
    if against is not None and cells is not None:  # the cell lists first: refused before any row is read
        _precheck_against(cells[~cells["cell_id"].isin(damaged)], against)
    try:
        from reports.build import build_report
    except ImportError as exc:
        raise BenchError(f"the report builder is not available: {exc}") from None
    from bench.store.completeness import incomplete_cells

    for d in damage:  # left out of the report (reports/data/store.py), never read as numbers
        typer.echo(f"bench: warning: {d.line()}", err=True)
    if cells is not None and "" not in damaged:  # a folder replaced: --repair, not "complete it" (D12)
        for cid, gap in incomplete_cells(store, cells).items():
            if cid not in damaged:
                typer.echo(f"bench: warning: cell {cid} is done but its rows are incomplete: {gap}; "
                           "rerun `bench run` to complete it", err=True)
    try:
        if against is not None:
            RunStore(against).require_run()
        built = build_report(run_dir, out, claims_at=claims_at.value, against=against)
    except PermissionError as exc:
        hint = "; write the report elsewhere with --out DIR" if out is None else ""
        raise BenchError(f"cannot write the report: {exc.filename or target}: permission denied{hint}") from None
    except OSError as exc:
        if exc.errno != getattr(os, "EROFS", 30):
            raise
        hint = "; write the report elsewhere with --out DIR" if out is None else ""
        raise BenchError(f"cannot write the report: {exc.filename or target}: read-only file system{hint}") from None
    typer.echo(f"report: {built / 'index.html'}  (also index.md, figures, tables, claims.md)")


def _precheck_against(cells: Any, against: Path) -> None:
    """``--against``'s checks of configurations and settings on the two runs' cells.parquet
    (reports/data/against.py), before the report loads any row."""
    from bench.store.run_store import RunStore
    from reports.data.against import check_cell_lists

    ref = RunStore(against)
    ref.require_run()
    ref_cells = ref.read_cells()
    if ref_cells is None:
        return  # load_store says what is missing, as before
    done = cells[cells["status"].fillna("pending").astype(str) == "done"]
    ref_done = ref_cells[ref_cells["status"].fillna("pending").astype(str) == "done"]
    check_cell_lists(done, ref_done, str(against))


@app.command()
def matrix(
    run: Path = typer.Option(..., "--run", help="Run directory with trained checkpoints."),
    n: list[int] = typer.Option([], "--n", help="Evaluation team size N' (repeat; default: the run's N values)."),
    p: list[float] = typer.Option([], "--p",
        help="Evaluation loss probability p' (repeat; default 0 0.2 0.4 0.6 0.8)."),
    loss_model: list[str] = typer.Option([], "--loss-model",
        help="bernoulli and/or gilbert_elliott (repeat; default both)."),
    burst: list[float] = typer.Option([], "--burst",
        help="Mean burst length of gilbert_elliott loss, steps (repeat; default 4 16)."),
    delay: list[float] = typer.Option([], "--delay",
        help="Evaluation mean message delay d', steps (repeat; default: the delays the run's cells trained at)."),
    delay_model: list[str] = typer.Option([], "--delay-model",
        help="fixed and/or geometric (repeat; default: the run's delayed cells' models, else fixed)."),
    episodes: int | None = typer.Option(None, "--episodes",
        help="Evaluation episodes per condition and mode (default: the run's eval_episodes)."),
    workers: int | None = typer.Option(None, "--workers", min=1,
        help="Worker actors (one core each) (default: all CPUs)."),
    address: str | None = typer.Option(None, "--address",
        help="Join a Ray cluster at host:port (or RAY_ADDRESS); default: embedded Ray."),
    repair: bool = typer.Option(False, "--repair",
        help="Move damaged or misplaced files of RUN/matrix/ to RUN/superseded/repair-<time>/ and evaluate those "
             "units again (without it such a matrix is refused, naming the file)."),
) -> None:
    """Robustness matrix: evaluate every trained checkpoint at other team sizes N', loss
    rates p', bursty (Gilbert-Elliott) loss and message delays d', on scenarios shared by
    every method, into RUN/matrix/. Rerunning skips the (cell, condition) units already written."""
    from bench.design.limits import check_count
    from bench.execute.matrix import run_matrix

    check_count("--episodes", "eval_episodes", episodes)
    check_count("--workers", "workers", workers)
    for size in n:
        check_count("--n", "n_robots", size)
    s = run_matrix(run, n, p, loss_model, burst, episodes, workers, address, repair=repair, delays=delay,
                   delay_models=delay_model)
    typer.echo(f"matrix: {s.units} units ({s.skipped} already done, {s.written} evaluated, "
               f"{s.unsupported} unsupported) in {s.wall_s:.1f} s -> {s.out / 'matrix'}")
    for unit, error in s.failed.items():
        typer.echo(f"bench: warning: matrix unit {unit} failed: {error}; rerun to retry", err=True)
    if s.failed:
        raise typer.Exit(1)


class ExportFormat(str, Enum):
    marl_eval = "marl-eval"
    csv = "csv"


@app.command()
def export(
    run: Path | None = typer.Option(None, "--run", help="Run directory (default: the most recent under results/)."),
    fmt: ExportFormat = typer.Option(..., "--format",
        help="marl-eval: marl-eval's raw-data JSON (environment / task / algorithm / run / step); csv: tidy "
             "cells.csv, train.csv, eval.csv."),
    out: Path | None = typer.Option(None, "--out",
        help="File (marl-eval) or folder (csv) to write (default: RUN/export/marl-eval.json or RUN/export/csv/). An "
             "existing file, at the default or at --out, is replaced only with --yes."),
    execution: str = typer.Option("argmax", "--execution",
        help="marl-eval: the execution mode exported (PIBT: planner, its only mode)."),
    balanced: bool = typer.Option(False, "--balanced",
        help="marl-eval: only the tasks every method ran, with the same seeds everywhere (what marl-eval's rliable "
             "matrices need)."),
    yes: bool = typer.Option(False, "--yes", "-y", help="Replace existing export files (default target or --out)."),
) -> None:
    """Write a run's results for other evaluators: marl-eval JSON or tidy CSV tables."""
    from bench.export.command import export_run

    written = export_run(_run_dir(run), fmt.value, out, execution=execution, balanced=balanced, overwrite=yes)
    for path in written:
        typer.echo(str(path))


def _writable(path: Path) -> bool:
    """Whether ``path`` (or its nearest existing parent) is a writable directory."""
    import os

    p = path
    while not p.exists() and p.parent != p:
        p = p.parent
    return p.is_dir() and os.access(p, os.W_OK | os.X_OK)


@app.command()
def replay(
    run: Path = typer.Option(..., "--run", help="Run directory."),
    cell: str = typer.Option(..., "--cell", help="cell_id (see cells.parquet)."),
    episode: int = typer.Option(0, "--episode", min=0, max=100_000,
        help="Evaluation episode to replay (below the cell's eval_episodes)."),
    out: Path | None = typer.Option(None, "--out",
        help="Output path (default: RUN/replays/<cell>-ep<K>[-<mode>].<format>)."),
    execution: str | None = typer.Option(None, "--execution",
        help="Execution mode of the episode: argmax (default), sample, sample@T; planner for pibt."),
    fmt: str = typer.Option("gif", "--format", help="gif, or mp4 (needs the imageio-ffmpeg package)."),
    fps: float = typer.Option(8.0, "--fps", min=0.5, max=60.0, help="Frames (steps) per second (0.5..60)."),
    force: bool = typer.Option(False, "--force",
        help="Replace an existing --out file (default: refused; the default path is rebuilt in place)."),
) -> None:
    """Render one evaluation episode of a cell, in one execution mode, as a captioned GIF or MP4."""
    from bench.store.run_store import RunStore

    run_dir = _run_dir(run)
    cells = RunStore(run_dir).read_cells()
    if cells is None or cell not in set(cells["cell_id"]):
        raise BenchError(f"cell {cell!r} is not in {str(run_dir / 'cells.parquet')!r}")
    try:
        from reports.replay import replay_progress, write_replay
    except ImportError as exc:
        raise BenchError(f"the replay writer is not available: {exc}") from None
    from bench.store.outputs import check_replay_out

    suffix = f"-{execution}" if execution else ""
    target = out if out is not None else run_dir / "replays" / f"{cell}-ep{episode}{suffix}.{fmt}"
    check_replay_out(target, out is None, force)
    with replay_progress() as progress:
        path = write_replay(run_dir, cell, episode, target, fps=fps, fmt=fmt, progress=progress,
                            execution=execution)
    typer.echo(str(path))


# -------------------------------------------------------------------- perf
PERF_SUITES = {
    "env": ("bench.perf.env", "run_env_suite"),
    "hierarchical": ("bench.perf.methods", "run_hierarchical_suite"),
    "baselines": ("bench.perf.baselines", "run_baselines_suite"),
    "pibt": ("bench.perf.pibt", "run_pibt_suite"),
    "train": ("bench.perf.methods", "run_train_suite"),  # env-steps/s per cell, N = 40 and 100; matmul FLOP/s
    "peers": ("bench.perf.peers", "run_peers_suite"),  # ours against TorchRL's MAPPO, N = 40 and 100
    "cli": ("bench.perf.cli", "run_cli_suite"),  # wall time of commands that do not train
    "protocol": ("bench.perf.protocol", "run_protocol_suite"),  # mappo's cost per env-step against the paper's
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
    print_frame(df, f"bench perf --suite {suite.value}")
    if json_path is not None:
        from envs.atomic import atomic_file

        with atomic_file(json_path) as fh:
            fh.write(df.to_json(orient="records", indent=2).encode())


def print_frame(df: Any, title: str) -> None:
    """Plain aligned text (wide tables stay readable in logs and narrow terminals)."""
    typer.echo(title)
    typer.echo(df.to_string(index=False, float_format=lambda v: f"{v:.4g}") if len(df) else "(no rows)")


# -------------------------------------------------------------------- tune
def _register_tune() -> None:
    from studies.cli import tune  # light: optuna, ray and torch load inside the command

    app.command("tune")(tune)


_register_tune()


def _register_commands() -> None:
    """Commands installed packages add (entry-point group ``warehouse_marl_bench.commands``,
    ``name = "module:function"``, a typer command function); e.g. the paper wing's
    ``bench calibrate``. Their modules import lightly; heavy imports run inside them."""
    from importlib import metadata

    for ep in metadata.entry_points(group="warehouse_marl_bench.commands"):
        app.command(ep.name)(ep.load())


_register_commands()


# -------------------------------------------------------------------- main
def _error(msg: str) -> None:
    text = " ".join(str(msg).split()).replace("Value error, ", "")
    print(f"bench: error: {text}", file=sys.stderr)


def main(argv: list[str] | None = None) -> None:
    """Console entry point: one-line errors with exit status 2 for user mistakes; Ctrl-C
    (exit 130) and SIGTERM (exit 143) stop every command with one line, its atomic writes
    having removed their temp files."""
    from bench.execute.signals import sigterm_as_interrupt, sigterm_received

    try:
        with sigterm_as_interrupt():
            code = app(args=argv, prog_name="bench", standalone_mode=False)
    except BaseException as exc:
        if sigterm_received() and isinstance(exc, (KeyboardInterrupt, typer.Abort)):
            _error(_TERMINATED)
            sys.exit(143)
        _exit_on(exc)
    if code == 130 and sigterm_received():  # typer turned Terminated into 130 too
        code = 143
    elif code == 130:  # Ctrl-C (typer turns KeyboardInterrupt into exit status 130)
        _error("interrupted; rerun the same command to resume")
    if code == 143:  # SIGTERM (bench run turns it into exit status 143)
        _error(_TERMINATED if not _is_run(argv) else "terminated; checkpoints are kept, rerun the same command to "
                                                     "resume")
    sys.exit(code if isinstance(code, int) else 0)


_TERMINATED = "terminated; no partial file was left behind; rerun the same command to resume"


def _is_run(argv: list[str] | None) -> bool:
    args = sys.argv[1:] if argv is None else argv
    return bool(args) and args[0] == "run"


def _exit_on(exc: BaseException) -> None:
    """Exit for an exception out of a command (re-raised when it is a bug)."""
    try:
        raise exc
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
    except OSError as exc:  # a full disk outside the store's own writes (which raise DiskFull)
        from envs.atomic import DiskFull, is_disk_full

        if not is_disk_full(exc):
            raise
        _error(str(DiskFull(exc.filename or "results")))
        sys.exit(2)


if __name__ == "__main__":
    main()
