"""Exports of a run for other evaluators: `bench export --format marl-eval|csv`.

May import: envs, algorithms, bench.design, bench.tracking, bench.store, bench.about (the layers of .importlinter).
"""
