"""The benchmark: what to run, running it, storing it, timing it, exporting it.

Subpackages by role, in layers (each imports only the layers below it; .importlinter
checks it in ``make lint``):

    cli                          the `bench` command line, the composition root
    execute | perf | export      running a grid; speed suites; exports for other evaluators
    design | tracking            cells, grids, costs, the paper's settings; experiment trackers
    store | about                the run folder's Parquet store; version and commit

May import: envs, algorithms (the CLI also reports and studies, which sit above).
"""
