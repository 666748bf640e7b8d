"""Torch settings of a process that runs methods (a worker, ``bench eval``, ``bench
matrix``), applied when the first method is built (``bench.execute.worker.build_method``),
before it exists: every ``Method`` uses torch from its constructor on, so torch is loaded
then and not before (a command that stops at a one-line error never loads it).

* One torch thread (the bench's parallelism is its workers; training numbers are those of
  one thread), or the cell's own count (``bench run --cell-threads K``, ``set_threads``): a
  second thread splits the weight-gradient products and the large reductions, so the numbers
  are a deterministic function of the inputs and the thread count but not those of one thread
  (docs/decisions/0242). A process that will run more than one thread sleeps at OpenMP
  barriers instead of spinning (``OMP_WAIT_POLICY=PASSIVE``, set before torch loads): a
  spinning thread on a busy core slowed a 2-thread training 14x here.
* Creating an optimizer does not import ``torch._dynamo`` (2-3 s): torch wraps
  ``Optimizer.add_param_group``, ``state_dict``, ``load_state_dict`` and ``zero_grad`` in
  ``torch._disable_dynamo``, which imports dynamo on the first call to build a wrapper that
  only matters while ``torch.compile`` traces. The bench compiles nothing, so the wrapper
  cached for each is the function itself (torch/_compile.py caches it in the function's
  ``__dynamo_disable``); the calls are the same calls. A torch without that cache, or a
  process that already loaded dynamo, is left alone. Training still loads dynamo at its
  first ``optimizer.step()`` (torch's graph-break marks), so what this spares is the
  evaluation of a trained or untrained learned method.

May import: nothing of the project.
"""
from __future__ import annotations

import os
import sys

__all__ = ["MAX_CELL_THREADS", "parse_cell_threads", "passive_wait", "prepare_torch", "set_threads"]

_DISABLED = ("add_param_group", "state_dict", "load_state_dict", "zero_grad")
MAX_CELL_THREADS = 64  # torch threads of one cell: past the cores of one machine a thread only waits


def parse_cell_threads(text: str | int) -> int:
    """``--cell-threads``: a count from 1 to MAX_CELL_THREADS; ValueError naming the value else.
    No ``auto``: the count enters a cell's numbers, so it is the user's choice, fixed per cell."""
    try:
        k = int(text)
    except ValueError:
        k = 0
    if not 1 <= k <= MAX_CELL_THREADS:
        raise ValueError(f"--cell-threads {text!r}: give a count of torch threads per cell from 1 to "
                         f"{MAX_CELL_THREADS} (no auto: the count changes a cell's numbers, docs/decisions/0242)")
    return k


def passive_wait() -> None:
    """OpenMP threads of this process sleep when idle (unless the user chose a policy); read
    once, when torch loads, so a no-op after that."""
    if "torch" not in sys.modules:
        os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def set_threads(threads: int) -> None:
    """Torch's intra-op threads for the next unit of work (a loaded torch: a cheap call)."""
    import torch

    if torch.get_num_threads() != threads:
        torch.set_num_threads(threads)


def prepare_torch(threads: int = 1) -> None:
    """Load torch with ``threads`` threads (default one) and no dynamo import for optimizer set-up."""
    if threads > 1:
        passive_wait()
    import torch

    torch.set_num_threads(threads)
    if "torch._dynamo" in sys.modules:
        return
    from torch.optim.optimizer import Optimizer

    for name in _DISABLED:
        fn = getattr(getattr(Optimizer, name, None), "__wrapped__", None)
        if fn is not None and getattr(fn, "__dynamo_disable", None) is None:
            fn.__dynamo_disable = fn
