"""``bench calibrate``: the paper wing's command, registered in the entry-point group
``warehouse_marl_bench.commands`` (pyproject.toml) so the harness's CLI never names it.

Light to import: ``bench --help`` loads this module; the claims load inside the command.
"""
from __future__ import annotations

import json
from pathlib import Path

import typer

__all__ = ["calibrate"]


def calibrate(
    sims: int = typer.Option(5000, "--sims", min=10, max=1_000_000,
                             help="Simulations per check and truth (5000: MC s.e. <= 0.005 for rates up to 14%)."),
    run: Path | None = typer.Option(None, "--run",
        help="Store whose per-seed spread is resampled (default: reproduction/paper)."),
    seed: int = typer.Option(0, "--seed", min=0, help="Seed of the simulations."),
    coverage_sims: int = typer.Option(2000, "--coverage-sims", min=10, help="Simulations for the CI coverage table."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON instead of tables."),
    out: Path | None = typer.Option(None, "--out", help="Also write the JSON here (e.g. RUN/report/calibration.json)."),
) -> None:
    """Rate of `supported` of every claim check under its null (must be <= 5% + 2 MC s.e.),
    its power under the stated effect, and its rate of `contradicted` where the claim holds
    or sits at its boundary (same limit), with each rate's MC s.e.: every check at its own
    seed counts and Bonferroni level, and every claim as a whole, on seed values resampled
    from the store's own spread (and a normal case); exit 1 if an error rate is too high."""
    import pandas as pd

    from bench.cli import print_frame
    from paper.claims.calibrate import calibration_report

    rep = calibration_report(sims, seed, coverage_sims=coverage_sims, run=run)
    text = json.dumps(rep, indent=2)
    if out is not None:
        from envs.atomic import atomic_file

        with atomic_file(out) as fh:
            fh.write(text.encode())
    if as_json:
        typer.echo(text)
    else:
        print_frame(pd.DataFrame(rep["calibration"]),
            f"bench calibrate ({sims} sims, null limit {rep['meta']['null_limit']})")
        print_frame(pd.DataFrame(rep["coverage"]), "coverage of 95% intervals over seeds")
    if not rep["all_null_ok"]:
        raise typer.Exit(1)
