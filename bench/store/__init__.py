"""What a run wrote: the crash-safe Parquet store of one run folder, its schema, atomic
writes and the completeness rule of a done cell.

May import: envs, algorithms.
"""
