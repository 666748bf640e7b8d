"""Figures: the paper's Fig. 1-3, the shared look, replay frames.

May import: envs, algorithms, bench, reports.data, reports.stats (the layers of .importlinter).
"""
