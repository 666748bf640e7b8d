"""Running it: the runner, its plan, worker actors and pool, the Ray cluster, progress,
quick evaluation and the condition matrix.

May import: envs, algorithms, bench.design, bench.tracking, bench.store, bench.about (the layers of .importlinter).
"""
