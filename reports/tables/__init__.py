"""Tables: Table I, the summary and success tables, progress, the ablation and the
leaderboard (with its figures).

May import: reports.data, reports.stats, reports.figures.
"""
