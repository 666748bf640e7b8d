"""A CUDA device simulated on the CPU, for testing the device path on a machine without one.

``FakeCuda`` is a context manager: inside it, ``tensor.to("cuda")``, ``module.to("cuda")``
and factories with ``device="cuda"`` give CPU tensors *tagged* as on the device (their
storage is remembered), ``tensor.device`` of a tagged tensor reads ``cuda:0``, and every
operation, backward passes included (a dispatch mode sees autograd's kernels too), raises
where real CUDA would:

* tensors of both kinds in one operation (a 0-dim host tensor is a scalar and allowed; the
  indices of an indexing operation may stay on the host; ``copy_`` may cross);
* a host ``torch.Generator`` drawing into a device tensor;
* ``.numpy()`` of a device tensor.

The numbers are the CPU's, so a run under ``FakeCuda`` must equal the CPU run bit for bit:
what it checks is where every tensor lives. It is a test helper (the real device check is
scripts/device_check.py on a machine with CUDA).
"""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import torch
from torch.overrides import TorchFunctionMode
from torch.utils._python_dispatch import TorchDispatchMode
from torch.utils._pytree import tree_flatten

CUDA = torch.device("cuda", 0)
_INDEX_OPS = {"index.Tensor", "index_put_.default", "index_put.default", "_index_put_impl_.default"}


class _State:
    def __init__(self) -> None:
        self.keep: dict[int, Any] = {}  # storage address -> storage (kept alive: no address reuse)
        self.quiet = 0  # > 0: results are not tagged (a copy to the host)

    def tagged(self, t: Any) -> bool:
        if not isinstance(t, torch.Tensor) or t.numel() == 0:
            return False
        try:
            return t.untyped_storage().data_ptr() in self.keep
        except (RuntimeError, NotImplementedError):
            return False

    def tag(self, out: Any) -> Any:
        for t in tree_flatten(out)[0]:
            if isinstance(t, torch.Tensor) and t.numel() > 0:
                s = t.untyped_storage()
                self.keep[s.data_ptr()] = s
        return out


def _is_cuda(device: Any) -> bool:
    return device is not None and torch.device(device).type == "cuda"


class _Functions(TorchFunctionMode):
    """Moves between host and the fake device; ``device`` reads; ``numpy`` refused."""

    def __init__(self, state: _State) -> None:
        super().__init__()
        self.s = state

    def __torch_function__(self, func: Any, types: Any, args: Any = (), kwargs: Any = None) -> Any:
        kwargs = kwargs or {}
        s = self.s
        name = getattr(func, "__name__", "")
        attr = getattr(getattr(func, "__self__", None), "__name__", "") if name == "__get__" else ""
        if attr == "device":
            return CUDA if s.tagged(args[0]) else func(*args, **kwargs)
        if attr == "is_cuda":
            return s.tagged(args[0])
        if name == "numpy" and s.tagged(args[0]):
            raise TypeError("can't convert cuda:0 device type tensor to numpy. Use Tensor.cpu() to copy the "
                            "tensor to host memory first.")
        if name in ("cpu", "cuda") or func is torch.Tensor.to:
            t = args[0]
            if name == "cpu":
                device, dtype, rest = torch.device("cpu"), None, {}
            elif name == "cuda":
                device, dtype, rest = CUDA, None, {}
            else:
                device, dtype, non_blocking, _ = torch._C._nn._parse_to(*args[1:], **kwargs)
                rest = {}
            if device is None:
                return func(*args, **kwargs)
            t2 = t if dtype is None else t.to(dtype)
            if _is_cuda(device):
                return t2 if s.tagged(t2) else s.tag(t2.clone())
            if not s.tagged(t2):
                return t2
            s.quiet += 1
            try:
                return t2.clone(**rest)
            finally:
                s.quiet -= 1
        if _is_cuda(kwargs.get("device")):
            return s.tag(func(*args, **{**kwargs, "device": "cpu"}))
        return func(*args, **kwargs)


class _Kernels(TorchDispatchMode):
    """Checks every kernel's operands and tags the results of device operands."""

    def __init__(self, state: _State) -> None:
        super().__init__()
        self.s = state

    def __torch_dispatch__(self, func: Any, types: Any, args: Any = (), kwargs: Any = None) -> Any:
        kwargs = kwargs or {}
        s = self.s
        name = f"{func._opname}.{func._overloadname}" if hasattr(func, "_opname") else str(func)
        tensors = [t for t in tree_flatten((args, kwargs))[0] if isinstance(t, torch.Tensor)]
        dev = [t for t in tensors if s.tagged(t)]
        if name.startswith("copy_") or name.startswith("_local_scalar_dense") or not dev:
            out = func(*args, **kwargs)
            return out
        operands = tensors
        if name in _INDEX_OPS:  # indices may stay on the host
            operands = [args[0]] + ([args[2]] if len(args) > 2 and isinstance(args[2], torch.Tensor) else [])
        inplace = func._opname.endswith("_") if hasattr(func, "_opname") else False
        host = [t for t in operands if not s.tagged(t) and (t.dim() > 0 or (inplace and t is args[0]))]
        if host and any(t.numel() > 0 for t in host):
            raise RuntimeError(f"Expected all tensors to be on the same device, but found at least two devices, "
                               f"cuda:0 and cpu! ({name}, host operand of shape {tuple(host[0].shape)})")
        gen = kwargs.get("generator")
        if gen is not None and gen.device.type != "cuda":
            raise RuntimeError(f"Expected a 'cuda' device type for generator but found 'cpu' ({name})")
        out = func(*args, **kwargs)
        return out if s.quiet else s.tag(out)


@contextmanager
def fake_cuda() -> Iterator[_State]:
    """Within: "cuda" is simulated on the CPU (see the module); torch.cuda reads as available."""
    state = _State()
    avail, count = torch.cuda.is_available, torch.cuda.device_count
    torch.cuda.is_available = lambda: True  # type: ignore[assignment]  # the simulated device
    torch.cuda.device_count = lambda: 1  # type: ignore[assignment]
    try:
        with _Functions(state), _Kernels(state):
            yield state
    finally:
        torch.cuda.is_available, torch.cuda.device_count = avail, count  # type: ignore[method-assign]
