"""Torch settings of a process that runs methods (a worker, ``bench eval``, ``bench
matrix``), applied when the first method is built (``bench.execute.worker.build_method``),
before it exists: every ``Method`` uses torch from its constructor on, so torch is loaded
then and not before (a command that stops at a one-line error never loads it).

* One torch thread (the bench's parallelism is its workers; training numbers are those of
  one thread).
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

import sys

__all__ = ["prepare_torch"]

_DISABLED = ("add_param_group", "state_dict", "load_state_dict", "zero_grad")


def prepare_torch() -> None:
    """Load torch with one thread and no dynamo import for optimizer set-up."""
    import torch

    torch.set_num_threads(1)
    if "torch._dynamo" in sys.modules:
        return
    from torch.optim.optimizer import Optimizer

    for name in _DISABLED:
        fn = getattr(getattr(Optimizer, name, None), "__wrapped__", None)
        if fn is not None and getattr(fn, "__dynamo_disable", None) is None:
            fn.__dynamo_disable = fn
