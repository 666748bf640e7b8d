"""Tables: the summary and success tables, progress, the leaderboard (with its figures),
who leads where and the robustness of training.

May import: envs, algorithms, bench, reports.figures, reports.data, reports.stats (the layers of .importlinter).
"""
