"""Figures: the paper's Fig. 1-3, the shared look, replay frames.

May import: reports.data, reports.stats.
"""
