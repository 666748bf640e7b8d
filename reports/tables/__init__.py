"""Tables: Table I, the summary and success tables, progress, the ablation and the
leaderboard (with its figures).

May import: envs, algorithms, bench, reports.figures, reports.data, reports.stats (the layers of .importlinter).
"""
