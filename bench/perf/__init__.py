"""How fast: `bench perf` suites (environment, methods, baselines, PIBT) and the
POGEMA/RWARE anchors, which run in their own venv.

May import: envs, algorithms, bench.design, bench.tracking, bench.store, bench.about (the layers of .importlinter).
"""
