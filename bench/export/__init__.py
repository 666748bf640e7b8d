"""Exports of a run for other evaluators: `bench export --format marl-eval|csv`.

May import: envs, algorithms, bench.design, bench.store.run_store.
"""
