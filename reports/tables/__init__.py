"""Tables: Table I, the summary and success tables, progress, the ablation, the
leaderboard (with its figures) and who leads where.

May import: envs, algorithms, bench, reports.figures, reports.data, reports.stats (the layers of .importlinter).
"""
