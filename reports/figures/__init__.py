"""Figures: the learning curves of every learned method, the shared look, replay frames.

May import: envs, algorithms, bench, reports.data, reports.stats (the layers of .importlinter).
"""
