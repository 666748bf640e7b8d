"""Statistics and verdicts: the paper's claims, their tests, their page and the
calibration of those tests.

May import: envs, algorithms, bench, reports.data, reports.stats (the layers of .importlinter).
"""
