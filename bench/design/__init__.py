"""What to run: cells (one validated config), grids and grid files, cost estimates, the
paper's settings (paper.py).

May import: envs, algorithms, bench.store, bench.about (the layers of .importlinter).
"""
