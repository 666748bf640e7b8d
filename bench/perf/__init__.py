"""How fast: `bench perf` suites (environment, methods, baselines, PIBT) and the
POGEMA/RWARE anchors, which run in their own venv.

May import: envs, algorithms, bench.design, bench.store.run_store.
"""
