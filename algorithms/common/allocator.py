"""Keep large tensor buffers in the process heap instead of fresh mmaps (glibc only).

A training update allocates and frees the same large activations every iteration (tens
of MB: (T B N, hidden) float32). glibc serves blocks above its mmap threshold with a
fresh ``mmap`` and returns them on free, so every such tensor is page-faulted and zeroed
by the kernel again: measured on the 2-core box, a (40000, 64) @ (64, 256) matmul takes
33 ms into a fresh block and 10 ms into a reused one, a ReLU over (160000, 128) 35 ms vs
13 ms. Raising the mmap and trim thresholds keeps those blocks in the heap for reuse. The
arithmetic is untouched (allocation only); the process keeps its peak heap instead of
returning it between updates, still bounded by one batch's working set.
``WAREHOUSE_BENCH_MALLOC_TUNE=0`` turns it off. Other platforms: nothing happens.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys

M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3  # glibc <malloc.h>
THRESHOLD_BYTES = 256 * 2**20  # blocks up to this size come from (and return to) the heap
_done = False


def tune_allocator() -> bool:
    """Raise glibc's mmap/trim thresholds once per process; True if they are set."""
    global _done
    if _done:
        return True
    if not sys.platform.startswith("linux") or os.environ.get("WAREHOUSE_BENCH_MALLOC_TUNE", "1") == "0":
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False  # not glibc
    _done = bool(mallopt(M_MMAP_THRESHOLD, THRESHOLD_BYTES)) and bool(mallopt(M_TRIM_THRESHOLD, THRESHOLD_BYTES))
    return _done
