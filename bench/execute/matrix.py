"""Robustness matrices: every trained checkpoint of a run on a grid of evaluation conditions.

The paper trains and evaluates a policy at the same team size N and loss rate p with
i.i.d. loss (Sec. IV). ``bench matrix --run DIR`` evaluates each done cell's checkpoint
at other conditions: team sizes N', mean loss probabilities p', loss models (Bernoulli,
and Gilbert-Elliott bursts of mean length b with the same mean p', envs/channel.py
``LossProcess``) and message delays d' (fixed or geometric, envs/channel.py ``DelayLine``;
default: the delays the run's cells trained at), in every execution mode of the cell
(argmax, sample, sample@T; planner). The channel axis is one product: every loss setting
at every delay setting (``delay_settings``); a delay of 0 has no model, as Bernoulli loss has
no burst length.

Pairing (docs/decisions/0100): the evaluation seed of a condition is
a hash of its layout and N' alone, never of the cell, and every unit is evaluated in
chunks of ``MATRIX_CHUNK`` episodes whatever the method's ``eval_chunk``. So episode k at
N' has the same starts and goals for every method, training condition, training seed,
p' and loss model (the ``scenario`` column is equal), and its loss draws come from the
same uniforms (their link sets differ by architecture: Z x Z groups vs N x N robots). The
delays are drawn from the channel's own child generator, so the loss draws of a condition
are those of its delay-0 twin as well.

Layout of N': a run whose cells share one layout keeps it; otherwise the layout the run's
cells trained at N' used (one per N, e.g. 'auto' presets); a run with several layouts and
no cell at N' is a BenchError. The grouping Z stays the cell's (robot i in group i mod Z,
any N' >= Z, algorithms/hierarchical/messages.py ``group_structure`` pads uneven groups),
so N' < Z cannot run: such units are stored as one row with status 'unsupported' and the
reason, as are checkpoints whose parameters do not load into the method built at N'.

Storage: ``DIR/matrix/<cell_id>/<condition>.parquet`` per (cell, condition) unit, written
atomically once all its chunks are in (``MATRIX_SCHEMA``: the eval metrics plus the
training and evaluation conditions). A rerun skips every unit whose file is complete
(K episodes x modes rows, or one 'unsupported' row); a condition at delay 0 keeps the file
name it had before the delay axis (a matrix file written then lacks the delay and MAPF
columns and reads as delay 0 with NaN MAPF metrics, ``ADDED_MATRIX_COLUMNS``); evaluation chunks
(bench/execute/worker.py ``CellWorker.eval_chunk``) run through the one executor
(bench/execute/executor.py: fan-out, retries and restarts as for ``bench run``).
"""
from __future__ import annotations

import hashlib
import json
import math
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from bench.design.cells import Cell
from bench.execute.executor import WAIT_S, Done, Executor, InProcessExecutor, RayExecutor, Retried
from bench.execute.executor import Unit as ExUnit
from bench.execute.plan import cell_spec, params_changes
from bench.execute.worker import CellWorker, build_method
from bench.store.completeness import expected_rows
from bench.store.run_store import RunStore, read_meta, write_table
from bench.store.schema import ADDED_EVAL_COLUMNS, METRIC_FIELDS, rows_to_table
from envs.config import LOSS_MODELS, EnvConfig, delay_error, loss_error
from envs.errors import BenchError
from envs.layouts import load_layout, preset_for
from envs.scenarios import main_region

DELAY_MODELS = ("fixed", "geometric")
DEFAULT_P = (0.0, 0.2, 0.4, 0.6, 0.8)
DEFAULT_BURSTS = (4.0, 16.0)
MATRIX_CHUNK = 10  # episodes per evaluation chunk of every unit (pairing across methods)
MATRIX_DIR = "matrix"
OK, UNSUPPORTED = "ok", "unsupported"

MATRIX_SCHEMA = pa.schema(
    [pa.field("cell_id", pa.string(), nullable=False), pa.field("method", pa.string()),
     pa.field("seed", pa.int64()), pa.field("train_n", pa.int64()), pa.field("train_p", pa.float64()),
     pa.field("train_loss_model", pa.string()), pa.field("eval_n", pa.int64()),
     pa.field("eval_p", pa.float64()), pa.field("loss_model", pa.string()),
     pa.field("burst_length", pa.float64()), pa.field("layout", pa.string()),
     pa.field("condition", pa.string()), pa.field("eval_seed", pa.int64()),
     pa.field("status", pa.string()), pa.field("reason", pa.string()),
     pa.field("episode", pa.int64(), nullable=False), pa.field("execution", pa.string()),
     pa.field("scenario", pa.string())]
    + METRIC_FIELDS
    + [pa.field("train_delay", pa.float64()), pa.field("train_delay_model", pa.string()),
       pa.field("eval_delay", pa.float64()), pa.field("delay_model", pa.string())]
    + [pa.field(name, pa.float64()) for name in ADDED_EVAL_COLUMNS]  # the MAPF metrics (throughput)
)
# Columns added after the first matrix files: a file without them is a delay-0 matrix
# (the only delay before the axis existed) whose MAPF metrics were not kept (NaN).
ADDED_MATRIX_COLUMNS: dict[str, Any] = {"train_delay": 0.0, "train_delay_model": "fixed", "eval_delay": 0.0,
                                        "delay_model": "fixed", **ADDED_EVAL_COLUMNS}


@dataclass(frozen=True)
class Condition:
    """One evaluation condition: team size N', mean loss p', loss model, burst length, layout,
    mean delay d' and delay model. ``burst_length`` is NaN for Bernoulli loss (it has none);
    ``delay_model`` is "fixed" at d' = 0 (no delay has no model)."""

    n: int
    p: float
    loss_model: str
    burst_length: float
    layout: str
    delay: float = 0.0
    delay_model: str = "fixed"

    @property
    def key(self) -> str:
        """File stem, e.g. 'n8-p0.2-bernoulli', 'n8-p0.2-ge-b16', 'n8-p0.2-bernoulli-d2' or
        'n8-p0.2-bernoulli-d2-geometric' (at d' = 0 the stem it had before the delay axis)."""
        loss = "bernoulli" if self.loss_model == "bernoulli" else f"ge-b{self.burst_length:g}"
        delay = "" if self.delay == 0 else f"-d{self.delay:g}" + ("" if self.delay_model == "fixed" else "-geometric")
        return f"n{self.n}-p{self.p:g}-{loss}{delay}"

    @property
    def seed(self) -> int:
        """Evaluation seed: a hash of the layout and N' only (never of the cell), so every
        method, training condition and seed sees the same scenarios here, and so do all
        p', loss models and delays at this N': the channel then draws the same uniforms, so
        Bernoulli losses are nested across p' (common random numbers, envs/channel.py)."""
        text = json.dumps(["matrix", self.layout, self.n])
        return int(hashlib.sha256(text.encode()).hexdigest()[:8], 16) % (2**31)

    def env(self, cell: Cell) -> EnvConfig:
        """The cell's environment at this condition (its Z, horizon, on_goal, task kept)."""
        base = cell.to_env_config().model_dump()
        base.update(n_robots=self.n, loss_p=self.p, loss_model=self.loss_model, layout=self.layout,
                    delay=self.delay, delay_model=self.delay_model)
        if not math.isnan(self.burst_length):
            base["burst_length"] = self.burst_length
        return EnvConfig.make(**base)


def delay_settings(delays: Sequence[float], models: Sequence[str]) -> list[tuple[float, str]]:
    """The delay axis: every d' > 0 under every delay model, d' = 0 once (no delay has no
    model: it is (0, "fixed")), in the order given."""
    out = [(0.0, "fixed") if d == 0 else (float(d), m) for d in delays for m in models]
    return list(dict.fromkeys(out))


def conditions(ns: Sequence[int], ps: Sequence[float], models: Sequence[str], bursts: Sequence[float],
               layout_of: Callable[[int], str],
               delays: Sequence[tuple[float, str]] = ((0.0, "fixed"),)) -> list[Condition]:
    """The grid N' x p' x (Bernoulli, GE per burst) x delay settings (``delay_settings``).
    Gilbert-Elliott only for 0 < p' < 1: at p' = 0 or 1 its chain is constant, the same
    channel as Bernoulli."""
    out: list[Condition] = []
    for n in ns:
        for p in ps:
            for m in models:
                if m == "bernoulli":
                    losses = [(m, math.nan)]
                elif 0.0 < p < 1.0:
                    losses = [(m, float(b)) for b in bursts]
                else:
                    continue
                out.extend(Condition(n, p, model, b, layout_of(n), d, dm) for model, b in losses for d, dm in delays)
    return out


def check_arguments(ns: Iterable[int], ps: Iterable[float], models: Iterable[str],
                    bursts: Iterable[float], episodes: int | None, delays: Iterable[float] = (),
                    delay_models: Iterable[str] = ()) -> None:
    """BenchError naming the first bad argument."""
    for n in ns:
        if int(n) < 1:
            raise BenchError(f"--n {n}: a team needs at least 1 robot")
    for p in ps:
        for m in models or LOSS_MODELS:
            for b in bursts or DEFAULT_BURSTS:
                found = loss_error(p, m, b)  # the one loss rule (envs/config.py)
                if found is not None:
                    names, why = found
                    raise BenchError(f"{' with '.join(_flag(n, p, m, b, len(names) > 1) for n in names)}: {why}")
    check_delays(delays, delay_models)
    if episodes is not None and episodes < 1:
        raise BenchError(f"--episodes {episodes}: evaluate at least 1 episode per condition")


def check_delays(delays: Iterable[float], models: Iterable[str]) -> None:
    """BenchError naming the first bad --delay or --delay-model: a mean delay is a finite
    number of steps >= 0, a fixed one a whole number within the environment's bound
    (``EnvConfig.delay_max``), a geometric mean below it (envs/config.py ``delay_error``)."""
    delays, models = list(delays), list(models)
    for m in models:
        if m not in DELAY_MODELS:
            raise BenchError(f"--delay-model {m!r}: unknown delay model; choose {' or '.join(DELAY_MODELS)}")
    bound = EnvConfig.model_fields["delay_max"].default
    for d in delays:
        if not (math.isfinite(d) and d >= 0.0):
            raise BenchError(f"--delay {d:g}: a mean message delay must be a finite number of steps >= 0")
        for m in models or ["fixed"]:
            why = delay_error(d, m, bound)
            if why is not None:
                why = why.split(": ", 1)[-1].replace("delay_model='geometric'", "--delay-model geometric")
                raise BenchError(f"--delay {d:g} with --delay-model {m}: {why}")


def _flag(name: str, p: float, model: str, burst: float, short: bool) -> str:
    """The option of a loss input as the user typed it, e.g. '--p 0.9' ('--p 0.9 with --burst 4')."""
    options = {"loss_p": ("--p", p), "loss_model": ("--loss-model", model), "burst_length": ("--burst", burst)}
    flag, value = options[name]
    return f"{flag} {value!r}" if isinstance(value, str) else f"{flag} {value:g}" if short else f"{flag} {value}"


def layout_chooser(cells: Sequence[Cell]) -> Callable[[int], str]:
    """The layout of N' (module docstring): the run's only layout, else the one its cells
    trained at N' used."""
    layouts = {c.layout for c in cells}
    per_n: dict[int, set[str]] = {}
    for c in cells:
        per_n.setdefault(c.n_robots, set()).add(c.layout)

    def choose(n: int) -> str:
        if len(layouts) == 1:
            return next(iter(layouts))
        found = per_n.get(n, set())
        if len(found) == 1:
            return next(iter(found))
        if found:
            raise BenchError(f"--n {n}: the run's cells at N={n} use several layouts "
                             f"({', '.join(sorted(found))}); cannot choose one")
        raise BenchError(f"--n {n}: the run uses several layouts ({', '.join(sorted(layouts))}) and "
                         f"no cell was trained at N={n}, so there is no layout for it "
                         f"(the preset sized for it would be {preset_for(n)})")
    return choose


def check_fits(n: int, layout: str) -> None:
    """BenchError when N' robots do not fit the layout's connected free cells."""
    region = len(main_region(load_layout(layout)))
    if n > region or (n == region == 1):
        raise BenchError(f"--n {n}: {n} robots do not fit layout {layout!r} ({region} connected free cells)")


@dataclass
class Unit:
    """One (cell, condition): its worker spec, chunks to do and rows collected."""

    cell: Cell
    cond: Condition
    modes: tuple[str, ...]
    episodes: int
    spec: dict[str, Any] = field(default_factory=dict)
    todo: list[tuple[str, int]] = field(default_factory=list)
    rows: dict[tuple[str, int], list[dict[str, Any]]] = field(default_factory=dict)
    retries: int = 0
    unavailable: int = 0  # calls refused while Ray restarted the worker (not deaths)
    error: str = ""

    def chunks(self) -> list[tuple[str, int]]:
        """Every (mode, chunk) of the unit, mode by mode (K episodes in MATRIX_CHUNK chunks)."""
        return [(m, c) for m in self.modes for c in range(math.ceil(self.episodes / MATRIX_CHUNK))]

    def columns(self) -> dict[str, Any]:
        c, d = self.cell, self.cond
        return {"cell_id": c.cell_id, "method": c.method, "seed": c.seed, "train_n": c.n_robots,
                "train_p": c.loss_p, "train_loss_model": c.loss_model, "eval_n": d.n, "eval_p": d.p,
                "loss_model": d.loss_model, "burst_length": d.burst_length, "layout": d.layout,
                "condition": d.key, "eval_seed": d.seed, "train_delay": c.delay,
                "train_delay_model": c.delay_model if c.delay > 0 else "fixed", "eval_delay": d.delay,
                "delay_model": d.delay_model}


@dataclass
class MatrixSummary:
    out: Path
    units: int
    skipped: int  # complete before this call
    written: int
    unsupported: int
    failed: dict[str, str]
    wall_s: float


def unit_path(run: Path, cell_id: str, cond: Condition) -> Path:
    return Path(run) / MATRIX_DIR / cell_id / f"{cond.key}.parquet"


def expected_unit_rows(cell: Cell, episodes: int, n_modes: int) -> int:
    """Rows of a complete 'ok' unit: the eval rule of bench/store/completeness.py with K episodes."""
    return expected_rows(True, 0, episodes, {}, n_modes).eval  # eval rows only: learned is moot


def unit_complete(path: Path, cell: Cell, episodes: int, n_modes: int) -> bool:
    """Whether a stored unit is complete for K = ``episodes`` (read from the footer)."""
    if not path.exists():
        return False
    try:
        meta = read_meta(path)
        rows = pq.read_metadata(path).num_rows
    except (BenchError, OSError):
        return False
    if meta.get("status") == json.dumps(UNSUPPORTED):
        return rows == 1
    return meta.get("episodes") == json.dumps(episodes) and rows == expected_unit_rows(cell, episodes, n_modes)


def done_cells(store: RunStore) -> list[Cell]:
    """Done cells of the run that have a checkpoint; BenchError when there is none."""
    cells = store.read_cells()
    if cells is None:
        raise BenchError(f"{str(store.root)!r} has no cells.parquet; run `bench run` first")
    done = cells[cells["status"] == "done"]
    out = [Cell.from_json(str(js)) for js in done["config_json"]]
    stale = [f"{c.cell_id} ({c.method}): {', '.join(d)}" for c, js in zip(out, done["params_json"], strict=True)
             if (d := params_changes(str(js), c))]
    if stale:  # the checkpoint would be loaded into the method built with today's defaults
        raise BenchError(f"{str(store.root)!r}: {len(stale)} done cell(s) were trained with other method "
                         f"parameters than this code resolves for them (a default changed since): "
                         f"{'; '.join(stale[:5])}; run `bench run --rerun-changed` on this run first")
    out = [c for c in out if store.ckpt_path(c.cell_id, c.method).exists()]
    if not out:
        raise BenchError(f"{str(store.root)!r} has no trained checkpoints of done cells "
                         "(checkpoints/<method>-<cell_id>.pt); run `bench run` to completion first")
    return out


def support_reason(cell: Cell, cond: Condition, state: dict[str, Any] | None) -> str:
    """'' when the cell's method runs at the condition, else why not (stored as 'unsupported')."""
    if cond.n < cell.groups:
        return (f"N'={cond.n} < Z={cell.groups}: the cell's {cell.groups} fixed groups (robot i in "
                f"group i mod Z) need at least {cell.groups} robots")
    try:
        spec = {"method_path": cell.method_path(), "env": cond.env(cell).model_dump(mode="json"),
                "params": cell.method_params().model_dump(mode="json"), "seed": cell.seed}
        method = build_method(spec)
        if state is not None:
            method.load_state_dict(state)
    except (BenchError, RuntimeError, ValueError, KeyError) as exc:
        return f"{cell.method} cannot run at N'={cond.n}: {' '.join(str(exc).split())[:300]}"
    return ""


def run_delays(cells: Sequence[Cell], delays: Sequence[float] | None,
               models: Sequence[str] | None) -> tuple[list[float], list[str]]:
    """The delay axis's values: those given, else the delays the run's cells trained at;
    the delay models given, else those of the run's delayed cells ("fixed" when none)."""
    ds = [float(d) for d in delays] if delays else sorted({float(c.delay) for c in cells})
    ms = list(models) if models else sorted({c.delay_model for c in cells if c.delay > 0}) or ["fixed"]
    return list(dict.fromkeys(ds)), list(dict.fromkeys(ms))


def plan_units(run: Path, ns: Sequence[int] | None = None, ps: Sequence[float] | None = None,
               models: Sequence[str] | None = None, bursts: Sequence[float] | None = None,
               episodes: int | None = None, delays: Sequence[float] | None = None,
               delay_models: Sequence[str] | None = None,
               ) -> tuple[list[Cell], list[Condition], list[Unit], int]:
    """Validate the arguments and the run; returns (cells, conditions, units to do, skipped)."""
    ns = list(ns or [])
    ps = list(DEFAULT_P if ps is None or len(ps) == 0 else ps)
    models = list(models or LOSS_MODELS)
    bursts = list(DEFAULT_BURSTS if bursts is None or len(bursts) == 0 else bursts)
    check_arguments(ns, ps, models, bursts, episodes, delays or [], delay_models or [])
    store = RunStore(run)
    store.require_run()
    cells = done_cells(store)
    ds, dms = run_delays(cells, delays, delay_models)
    check_delays(ds, dms)
    ns = ns or sorted({c.n_robots for c in cells})
    choose = layout_chooser(cells)
    for n in dict.fromkeys(ns):
        check_fits(int(n), choose(int(n)))
    conds = conditions([int(n) for n in dict.fromkeys(ns)], [float(p) for p in dict.fromkeys(ps)],
                       list(dict.fromkeys(models)), [float(b) for b in dict.fromkeys(bursts)], choose,
                       delay_settings(ds, dms))
    k = episodes if episodes is not None else max(c.eval_episodes for c in cells)
    units, skipped = [], 0
    for cell in cells:
        modes = cell.execution_modes()
        for cond in conds:
            if unit_complete(unit_path(run, cell.cell_id, cond), cell, k, len(modes)):
                skipped += 1
                continue
            units.append(Unit(cell, cond, modes, k))
    return cells, conds, units, skipped


def _prepare(unit: Unit) -> None:
    """The worker spec of a unit (its cache key names the condition) and its chunks."""
    params = unit.cell.method_params().model_dump(mode="json")
    params["eval_chunk"] = MATRIX_CHUNK
    unit.spec = {**cell_spec(unit.cell), "cell_id": f"{unit.cell.cell_id}@{unit.cond.key}",
                 "env": unit.cond.env(unit.cell).model_dump(mode="json"), "params": params,
                 "seed": unit.cond.seed}
    unit.todo = unit.chunks()


def _check_matrix_files(store: RunStore, repair: bool) -> bool:
    """Refuse (or with ``repair`` move aside) damaged or misplaced files of RUN/matrix/; the
    files written next are recorded in checksums.json when the run's checksums are in force."""
    from datetime import datetime, timezone

    from bench.store.integrity import find_damage, move_aside

    checks = store.integrity()
    damage = [d for d in find_damage(store, checks) if d.rel.split("/")[0] == "matrix"]
    if damage and not repair:
        raise BenchError(f"{store.root}: {damage[0].line()}")
    if checks.active:
        checks.start_recording()
    return move_aside(store, checks, damage, datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%SZ")) is not None


def _write_unit(run: Path, unit: Unit, status: str, reason: str = "", store: RunStore | None = None) -> None:
    base = {**unit.columns(), "status": status, "reason": reason}
    if status == UNSUPPORTED:
        rows = [{**base, "episode": -1, "execution": ",".join(unit.modes), "scenario": "", "steps": None}]
    else:  # mode by mode, episode by episode; the last chunk may run past K
        rows = [{**r, **base} for u in unit.chunks() for r in unit.rows[u]
                if int(r["episode"]) < unit.episodes]
    meta = {"status": json.dumps(status), "episodes": json.dumps(unit.episodes)}
    write_table(unit_path(run, unit.cell.cell_id, unit.cond), rows_to_table(rows, MATRIX_SCHEMA, meta),
                store.checksums if store is not None else None)


def run_matrix(run: Path | str, ns: Sequence[int] | None = None, ps: Sequence[float] | None = None,
               models: Sequence[str] | None = None, bursts: Sequence[float] | None = None,
               episodes: int | None = None, workers: int | None = None, address: str | None = None,
               use_ray: bool = True, on_unit: Callable[[Unit], None] | None = None,
               repair: bool = False, delays: Sequence[float] | None = None,
               delay_models: Sequence[str] | None = None) -> MatrixSummary:
    """Evaluate every missing (cell, condition) unit of the run; see the module docstring.

    A damaged or misplaced matrix file (bench/store/integrity.py) is a BenchError naming it, unless
    ``repair``: then it moves to superseded/repair-<time>/ and its unit is evaluated again.
    ``use_ray=False`` runs the same worker code in this process (tests, one core)."""
    t0 = time.monotonic()
    run = Path(run)
    def plan() -> tuple[list[Cell], list[Condition], list[Unit], int]:
        return plan_units(run, ns, ps, models, bursts, episodes, delays, delay_models)

    _, _, units, skipped = plan()
    store = RunStore(run)
    lock = store.lock()
    try:
        if _check_matrix_files(store, repair):  # moved aside: those units are to do again
            _, _, units, skipped = plan()
        states: dict[str, dict[str, Any] | None] = {}
        support: dict[tuple[str, int, str], str] = {}
        todo: list[Unit] = []
        unsupported = 0
        for unit in units:
            cid = unit.cell.cell_id
            if cid not in states:
                ckpt = store.read_checkpoint(cid, unit.cell.method)
                states[cid] = ckpt["state"] if ckpt is not None else None
            key = (cid, unit.cond.n, unit.cond.layout)
            if key not in support:
                support[key] = support_reason(unit.cell, unit.cond, states[cid])
            if support[key]:
                _write_unit(run, unit, UNSUPPORTED, support[key], store)
                unsupported += 1
                if on_unit is not None:
                    on_unit(unit)
                continue
            _prepare(unit)
            todo.append(unit)
        failed: dict[str, str] = {}
        written = 0

        def finish(unit: Unit) -> None:
            nonlocal written
            if unit.error:
                failed[f"{unit.cell.cell_id}/{unit.cond.key}"] = unit.error
                return
            _write_unit(run, unit, OK, store=store)
            written += 1
            if on_unit is not None:
                on_unit(unit)

        if todo:
            _evaluate(todo, states, finish, workers, address, use_ray)
    finally:
        if lock is not None:
            import os

            os.close(lock)
    return MatrixSummary(run, len(units) + skipped, skipped, written, unsupported, failed,
                         time.monotonic() - t0)


def _evaluate(units: list[Unit], states: dict[str, Any], finish: Callable[[Unit], None],
              workers: int | None, address: str | None, use_ray: bool) -> None:
    """Every (mode, chunk) of every unit through the executor (bench/execute/executor.py): in
    this process on one worker, or fanned out over Ray worker actors; a unit is finished
    once all its chunks are back, or failed at its first chunk that failed."""
    ctx = None
    try:
        if use_ray:
            import ray

            from bench.execute.ray_cluster import connect

            ctx = connect(address, workers)
            refs: dict[str, Any] = {cid: ray.put(s) for cid, s in states.items() if s is not None}
            ex: Executor = RayExecutor(CellWorker, max(1, min(workers or ctx.cpus, ctx.cpus)), ctx)
        else:
            refs = {cid: s for cid, s in states.items() if s is not None}
            ex = InProcessExecutor(CellWorker)
        left = {id(u): len(u.todo) for u in units}  # chunks of the unit not yet back
        for unit in units:
            box = [refs[unit.cell.cell_id]] if unit.cell.cell_id in refs else []
            for mode, chunk in unit.todo:
                ex.submit(ExUnit("eval_chunk", (unit.spec, box, chunk, mode), id(unit), tag=(unit, (mode, chunk))))
        try:
            while any(left.values()):
                for outcome in ex.wait(WAIT_S):
                    unit, work = outcome.unit.tag
                    if isinstance(outcome, Retried):
                        continue
                    settled = 1
                    if isinstance(outcome, Done):
                        unit.rows[work] = outcome.result["rows"]
                    else:  # drop its queued chunks: nothing of a failed unit is written
                        unit.error = unit.error or outcome.message
                        settled += ex.release(id(unit))
                    left[id(unit)] -= settled
                    if left[id(unit)] == 0:
                        finish(unit)
        finally:
            if isinstance(ex, RayExecutor):
                ex.close(keep=ctx is not None and not ctx.started_here)
    finally:
        if ctx is not None:
            ctx.shutdown()


def read_matrix(run: Path | str, problems: list[str] | None = None) -> pa.Table | None:
    """Every stored unit of ``DIR/matrix/`` as one table (None when there is none), read by
    the run's one row reader (``RunStore.read_rows``; a file written before the delay axis
    gets ``ADDED_MATRIX_COLUMNS`` at their values). With a ``problems`` list, an unreadable
    or misplaced file is skipped and named there instead of raising."""
    root = Path(run) / MATRIX_DIR
    if not (root.is_dir() and any(p for p in root.glob("*/*.parquet") if not p.name.startswith("."))):
        return None
    table = RunStore(run).read_rows(root, MATRIX_SCHEMA, problems, added=ADDED_MATRIX_COLUMNS)
    return table if table.num_rows else None
