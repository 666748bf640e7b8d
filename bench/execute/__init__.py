"""Running it: the one executor (in-process and Ray forms), the runner and its plan, the
worker actors, the Ray cluster, progress, quick evaluation and the condition matrix.

May import: envs, algorithms, bench.design, bench.tracking, bench.store, bench.about (the layers of .importlinter).
"""
