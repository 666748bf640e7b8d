"""Statistics and verdicts: the paper's claims, their tests, their page and the
calibration of those tests.

May import: reports.data, reports.stats, reports.figures (styles).
"""
