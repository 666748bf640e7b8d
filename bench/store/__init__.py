"""What a run wrote: the crash-safe Parquet store of one run folder, its schema, the
completeness rule of a done cell and the file names of a study folder (its writes go
through envs/atomic.py).

May import: envs, algorithms (the layers of .importlinter).
"""
