"""The report of any run, for any method: data loading, statistics, figures, tables and pages.

It knows no method and no paper: every method of a run is shown by the label, colour and
line style the report's method table gives it, and packages add their own sections after
the generic ones through ``reports.sections`` (the paper's reproduction does so from its
wing, ``paper/``, on the floor above).

Modules by role, in layers (each imports only the layers below it; .importlinter checks
it in ``make lint``):

    build                         writes every output of a run's report
    matrix | replay | sections    the robustness-matrix section; `bench replay` clips;
                                  the plug-in point of registered sections
    pages                         index.md / index.html
    tables | writers              tables; the atomic file writers
    figures                       learning curves, the shared look
    improvement                   probability of improvement: its intervals and their coverage
    data | stats                  a run's store as frames; statistics

May import: envs, algorithms, bench.
"""
