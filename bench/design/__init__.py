"""What to run: cells (one validated config), grids and grid files, cost estimates.

May import: envs, algorithms, bench.store.run_store.
"""
