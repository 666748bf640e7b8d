"""``bench tune``: run or resume an Optuna study, or print its best configuration.

``tune`` is a typer command function; bench/cli.py registers it as ``bench tune``.
``tune_study`` is the same thing as a Python call (used by the tests). Options left out
on a rerun come from the stored study, so ``bench tune --study demo --trials 16`` resumes
``demo`` with its original N, p, layout, space and seed; repeating a different value is
an error. User mistakes raise ``BenchError``, which ``bench``'s entry point prints as one
line on stderr with exit status 2; Ctrl-C leaves a resumable study.
"""
from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from envs.errors import BenchError
from studies import DEFAULT_ROOT
from studies.seeds import PUBLISHED_ROOT

__all__ = ["TuneResult", "print_best", "tune", "tune_study"]

if TYPE_CHECKING:
    from studies.runner import RunSummary

# CLI option name -> TrialSettings field
SETTING_OPTIONS = ("method", "n_robots", "loss_p", "layout", "groups", "episodes", "horizon",
                   "eval_episodes", "objectives")


@dataclass
class TuneResult:
    summary: RunSummary
    directory: Path
    files: list[Path]
    best: dict[str, Any] | None  # the best configuration (mean over replicates, CI), if any
    best_reason: str  # why there is no best yet ("" when there is one)
    coverage: str  # "20 of 20 configurations have >= 2 finished replicates"


PLAN_OPTIONS = ("search", "replicates", "prune_warmup", "prune_min_rho")


def tune_study(name: str, n_trials: int | None, options: dict[str, Any], *, storage: str | None = None,
               root: Path | str = DEFAULT_ROOT, workers: int | None = None,
               address: str | None = None, inline: bool = False,
               log: Callable[[str], None] = lambda _m: None,
               progress: Callable[[Any], None] = lambda _s: None,
               published: Path | None = PUBLISHED_ROOT) -> TuneResult:
    """Run study ``name`` until it holds ``n_trials`` finished trials, then export + report.

    ``options`` holds what the user set explicitly: any ``TrialSettings`` field plus
    ``seed``, ``c_max`` (bool: search C_max), ``param`` (list of ``NAME=VALUES``),
    ``pruner``, ``search`` (auto/grid/tpe), ``replicates``, ``prune_warmup`` and
    ``prune_min_rho``. For a resumed study the stored values fill in the rest.
    ``n_trials`` None: every point ``replicates`` times (grid), else 20. The study's
    seeds must be disjoint from every seed the committed grids under ``published`` evaluate
    (studies/seeds.py; None: no check).
    """
    import optuna

    from studies.export import best_configuration, trials_frame, write_trials
    from studies.objective import TrialSettings
    from studies.points import coverage
    from studies.pruning import warmup_step
    from studies.report import build_study_report
    from studies.runner import make_pruner, preflight, run_study
    from studies.schedule import SearchPlan
    from studies.seeds import check_tuning_seeds, published_seeds
    from studies.space import plain, space_size
    from studies.storage import (
        CONFIG_ATTR,
        merge_config,
        open_storage,
        open_study,
        stored_config,
        study_dir,
    )

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    if n_trials is not None and n_trials < 1:
        raise BenchError(f"--trials must be >= 1, got {n_trials}")
    from bench.design.limits import check_count

    check_count("--trials", "trials", n_trials)
    check_count("--workers", "workers", workers)
    directory = study_dir(name, root)
    given = _config(options)  # bad options fail before anything is written
    published_seed_map = published_seeds(published)
    check_tuning_seeds(given["seed"], given["replicates"], published_seed_map)
    store = open_storage(storage, directory, log)
    explicit = set(options) - {"c_max", "param"} | ({"space"} if {"c_max", "param"} & set(options) else set())
    stored = stored_config(store, name)
    config = merge_config(name, stored, given, explicit)
    settings = TrialSettings.make(**{k: v for k, v in config.items() if k in TrialSettings.model_fields})
    space = {k: tuple(v) for k, v in config["space"].items()}
    check_tuning_seeds(config["seed"], config["replicates"], published_seed_map)  # a resumed study's own
    preflight(settings, space)
    plan = SearchPlan.make(config["search"], space, config["replicates"], config["seed"])
    pruner = make_pruner(config["pruner"], settings.multi_objective, settings.iterations,
                         config["prune_warmup"], config["prune_min_rho"])
    if n_trials is None:
        n_trials = plan.default_trials()
    study = open_study(name, store, settings.directions, config["seed"], pruner)
    if not stored:
        study.set_user_attr(CONFIG_ATTR, config)
    pruning = config["pruner"] != "none" and not settings.multi_objective
    log(f"study {name}: {space_size(space)} configurations "
        f"({', '.join(f'{k} in {list(v)}' for k, v in space.items())}); "
        f"{plan.mode} search, {plan.replicates} replicate(s) per configuration, {n_trials} trials; "
        f"N={settings.n_robots}, p={settings.loss_p}, layout={settings.layout}, "
        f"{settings.episodes} episodes x horizon {settings.horizon}; "
        + (f"pruning from update {warmup_step(settings.iterations, config['prune_warmup'])} of "
           f"{settings.iterations} when rank correlation >= {config['prune_min_rho']}"
           if pruning else "no pruning"))
    if inline:
        from studies.executors import SequentialExecutor

        executor: Any = SequentialExecutor(workers or 1)
    else:
        from studies.executors import RayExecutor

        executor = RayExecutor(workers, address=address)
    summary = run_study(study, settings, space, config["seed"], n_trials, executor,
                        pruning=config["pruner"] != "none", log=log, plan=plan, progress=progress)
    extra = {"search_resolved": plan.mode, "space_size": space_size(space), "iterations": settings.iterations,
             "warmup_step": warmup_step(settings.iterations, config["prune_warmup"]) if pruning else None}
    files = [write_trials(study, directory, extra)]
    files += build_study_report(directory)
    best, reason = None, ""
    try:
        row = best_configuration(study)
        best = {"params": {k: plain(row[k]) for k in space}, **{k: row[k] for k in (
            "value", "ci_low", "ci_high", "complete", "success_rate", "team_return", "trials")}}
    except BenchError as exc:
        reason = str(exc)
    cover = coverage(trials_frame(study), space_size(space), plan.replicates)
    return TuneResult(summary, directory, files, best, reason, cover)


def _config(options: dict[str, Any]) -> dict[str, Any]:
    """The full config for a new study: defaults overridden by ``options``."""
    from studies.objective import TrialSettings
    from studies.space import (
        C_MAX_CHOICES,
        PARAMETERS,
        has_paper_space,
        method_space,
        parse_overrides,
        search_space,
        split_overrides,
    )

    settings = TrialSettings.make(**{k: v for k, v in options.items() if k in TrialSettings.model_fields})
    texts = options.get("param") or []
    names = set(split_overrides(texts))
    if has_paper_space(settings.method) and names <= set(PARAMETERS):  # the paper's study
        space = search_space(c_max=bool(options.get("c_max")), overrides=parse_overrides(texts))
    else:  # any declared hyperparameter of the method, by the same protocol
        space = method_space(settings.method, split_overrides(texts)
                             | ({"c_max": [str(v) for v in C_MAX_CHOICES]} if options.get("c_max")
                                and "c_max" not in split_overrides(texts) else {}))
    from studies.pruning import MIN_RHO, WARMUP, warmup_step
    from studies.schedule import resolve_mode

    resolve_mode(options.get("search", "auto"), space)  # an unknown mode fails here
    replicates = int(options.get("replicates", 2))
    if replicates < 1:
        raise BenchError(f"--replicates must be >= 1, got {replicates}")
    from bench.design.limits import check_count

    check_count("--replicates", "replicates", replicates)
    warmup = float(options.get("prune_warmup", WARMUP))
    warmup_step(settings.iterations, warmup)  # validates the range
    min_rho = float(options.get("prune_min_rho", MIN_RHO))
    if not -1.0 <= min_rho <= 1.0:
        raise BenchError(f"--prune-min-rho must be in [-1, 1], got {min_rho}")
    return {**settings.model_dump(mode="json"), "space": {k: list(v) for k, v in space.items()},
            "seed": int(options.get("seed", 0)), "pruner": options.get("pruner", "median"),
            "search": options.get("search", "auto"), "replicates": replicates,
            "prune_warmup": warmup, "prune_min_rho": min_rho}


def _from_definition(path: Path, study: str | None, trials: int | None, options: dict[str, Any],
                     estimate: bool) -> tuple[str, int, dict[str, Any]]:
    """(study name, trials, options) of definition ``path``; with ``estimate``, print its
    cost instead. Options the definition fixes may not be given beside it."""
    from studies.definitions import estimate as cost_of
    from studies.definitions import load_definition

    if study is not None or options:
        given = ["--study"] if study is not None else []
        given += [f"--{k.replace('_', '-')}" for k in options]
        raise BenchError(f"--definition {str(path)!r} fixes the study, its protocol and its space; "
                         f"drop {given[0]}")
    d = load_definition(path)
    _config(d.options)  # its space and settings are valid for its method
    if estimate:
        e = cost_of(d)
        s = e["settings"]
        typer.echo(f"study {d.name}: {s.method}, {d.trials} trials of {s.episodes} episodes x horizon "
                   f"{s.horizon} at N={s.n_robots}, p={s.loss_p}, {s.layout}; per trial about "
                   f"{e['trial_s'] / 60:.1f} min (training {e['train_s'] / 60:.1f}, evaluations "
                   f"{e['eval_s'] / 60:.1f}); about {e['worker_hours']:.1f} worker-hours with no trial pruned "
                   f"(bench grids' rates, good to a factor of 2)")
    return d.name, trials if trials is not None else d.trials, dict(d.options)


def print_best(name: str, storage: str | None = None, root: Path | str = DEFAULT_ROOT) -> str:
    """The best configuration of study ``name`` as a grid-file snippet."""
    import optuna

    from studies.export import best_grid_snippet
    from studies.storage import open_storage, study_dir

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    directory = study_dir(name, root)
    if storage is None and not directory.exists():
        raise BenchError(f"no study {name!r} under {str(Path(root))!r}; run `bench tune --study {name}` first")
    store = open_storage(storage, directory)
    if name not in optuna.study.get_all_study_names(store):
        raise BenchError(f"no study {name!r} in the storage")
    return best_grid_snippet(optuna.load_study(study_name=name, storage=store))


def tune(
    study: str | None = typer.Option(None, "--study", help="study name (resumes if it exists)"),
    best: str | None = typer.Option(None, "--best", metavar="STUDY",
                                       help="print the best configuration of STUDY as a grid file and exit"),
    trials: int | None = typer.Option(None, "--trials",
                                      help="finished (complete + pruned) trials the study should hold "
                                           "(default: every configuration x --replicates for a grid search, else 20)"),
    search: str | None = typer.Option(None, "--search",
                                      help="auto (grid for <= 64 configurations, else TPE), grid or tpe (default: "
                                           "auto)"),
    replicates: int | None = typer.Option(None, "--replicates",
                                          help="seed replicates per configuration; best = highest mean (default: 2)"),
    prune_warmup: float | None = typer.Option(None, "--prune-warmup",
                                              help="fraction of training before pruning may act (default: 0.5)"),
    prune_min_rho: float | None = typer.Option(None, "--prune-min-rho",
                                               help="rank correlation (value at the step vs final) needed to prune "
                                                    "(default: 0.7)"),
    n_robots: int | None = typer.Option(None, "--n-robots", help="team size N (default: 8)"),
    loss_p: float | None = typer.Option(None, "--loss-p", help="message loss probability p (default: 0.2)"),
    layout: str | None = typer.Option(None, "--layout", help="layout preset or .map path (default: tiny)"),
    groups: int | None = typer.Option(None, "--groups", help="number of groups Z (default: 4)"),
    episodes: int | None = typer.Option(None, "--episodes", help="training episodes per trial (default: 48)"),
    horizon: int | None = typer.Option(None, "--horizon", help="episode length T (default: 48)"),
    eval_episodes: int | None = typer.Option(None, "--eval-episodes", help="final evaluation episodes (default: 20)"),
    objectives: str | None = typer.Option(None, "--objectives",
                                             help="'success' (return breaks ties) or 'success,return' "
                                                  "(multi-objective, no pruning)"),
    c_max: bool | None = typer.Option(None, "--c-max/--no-c-max", help="also search C_max (default: no)"),
    param: list[str] | None = typer.Option(None, "--param", metavar="NAME=VALUES",
                                              help="the choices of a parameter, e.g. ref_size=4,8 or "
                                                   "search_radius=1..3, "
                                                   "or any hyperparameter of --method, e.g. lr=1e-3,3e-3 (repeatable)"),
    pruner: str | None = typer.Option(None, "--pruner",
                                      help="median (after the warm-up, gated by the rank correlation) or none "
                                           "(default: median)"),
    seed: int | None = typer.Option(None, "--seed", help="study seed (trial seeds derive from it) (default: 0)"),
    storage: str | None = typer.Option(None, "--storage", metavar="URL",
                                          help="RDB URL of a shared study database (default: journal file under "
                                               "results/studies/)"),
    workers: int | None = typer.Option(None, "--workers", help="trials run in parallel (default: CPU count)"),
    address: str | None = typer.Option(None, "--address",
        help="join this Ray cluster (else RAY_ADDRESS, else embedded)"),
    out: Path = typer.Option(DEFAULT_ROOT, "--out", help="root folder of the studies"),
    inline: bool = typer.Option(False, "--inline", help="run trials in this process, without Ray (debugging)"),
    method: str | None = typer.Option(None, "--method", help="the learned method to tune: a registered name or "
                                      "module:Class (default: hierarchical); its hyperparameters: `bench methods M`"),
    definition: Path | None = typer.Option(None, "--definition", metavar="FILE",
        help="run the committed study definition FILE (studies/definitions/*.toml: the published protocol); "
             "only --trials, --workers, --inline, --out, --storage and --address may go with it"),
    estimate: bool = typer.Option(False, "--estimate", help="with --definition: print the study's cost "
                                  "(worker-hours, no trial pruned) and exit"),
) -> None:
    """Tune a learned method with Optuna by one protocol for every method: by default |R_z|
    (ref_size) and L (search_radius) of the hierarchical method (the paper's study), else
    any declared hyperparameter of --method given with --param NAME=VALUES."""
    if best is not None:
        typer.echo(print_best(best, storage, out), nl=False)
        return
    if estimate and definition is None:
        raise BenchError("--estimate needs --definition FILE")
    local = {"method": method, "n_robots": n_robots, "loss_p": loss_p, "layout": layout,
             "groups": groups, "episodes": episodes, "horizon": horizon,
             "eval_episodes": eval_episodes, "objectives": objectives, "c_max": c_max,
             "param": param or None, "pruner": pruner, "seed": seed, "search": search,
             "replicates": replicates, "prune_warmup": prune_warmup, "prune_min_rho": prune_min_rho}
    options = {k: v for k, v in local.items() if v is not None}
    if definition is not None:
        study, trials, options = _from_definition(definition, study, trials, options, estimate)
        if estimate:
            return
    if study is None:
        raise BenchError("give --study NAME (or --best STUDY, or --definition FILE)")
    if workers is not None and workers < 1:
        raise BenchError(f"--workers must be >= 1, got {workers}")
    from studies.progress import make_bar

    t0 = time.perf_counter()
    bar = None

    def progress(snap: Any) -> None:
        nonlocal bar
        if bar is None:
            bar = make_bar(snap.requested)
        if bar is not None:
            bar.update(snap)

    def log(message: str) -> None:
        if bar is not None:
            bar.log(message)
        else:
            typer.echo(message, err=True)

    try:
        res = tune_study(study, trials, options, storage=storage, root=out, workers=workers,
                         address=address, inline=inline, log=log, progress=progress)
    finally:
        if bar is not None:
            bar.close()
    s = res.summary
    typer.echo(f"study {study}: {s.finished}/{s.requested} finished trials "
               f"({s.complete} complete, {s.pruned} pruned, {s.failed} failed"
               + (f", {s.running_elsewhere} running elsewhere" if s.running_elsewhere else "")
               + f"); {s.started} run now in {time.perf_counter() - t0:.1f} s")
    typer.echo(f"reason: {s.reason()}")
    typer.echo(f"coverage: {res.coverage}")
    if res.best:
        b = res.best
        params = ", ".join(f"{k}={v}" for k, v in b["params"].items())
        typer.echo(f"best: {params}: mean objective {b['value']:.4f} over {int(b['complete'])} replicates "
                   f"(95% CI {b['ci_low']:.4f} .. {b['ci_high']:.4f}; trials {b['trials']})")
    else:
        typer.echo(f"best: withheld, {res.best_reason}")
    typer.echo(f"trials: {res.files[0]}\nreport: {res.directory / 'report' / 'study.html'}")
    typer.echo(f"best configuration as a grid file: bench tune --best {study}"
               + (f" --out {out}" if Path(out) != DEFAULT_ROOT else ""))
    sys.stdout.flush()
