"""The report of a run: data loading, statistics, claims, figures, tables and pages.

Modules by role, in layers (each imports only the layers below it; .importlinter checks
it in ``make lint``):

    build                        writes every output of a run's report
    matrix | replay              the robustness-matrix section; `bench replay` clips
    pages                        index.md / index.html
    claims | tables | writers    claims and their tests; tables; the atomic file writers
    figures                      Fig. 1-3, the shared look
    data | stats                 a run's store as frames; statistics

May import: envs, algorithms, bench.
"""
