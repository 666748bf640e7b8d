"""Reading runs: a run's store as data frames, variants of a configuration, and the
merge of another run's cells (--against).

May import: envs, algorithms, bench (not reports.stats, its sibling) (the layers of .importlinter).
"""
