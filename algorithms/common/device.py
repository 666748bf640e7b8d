"""The torch device a learned method's networks run on: an execution choice, not a parameter.

``Method(env, params, seed, device=...)`` places the networks, their optimizers' states and
the tensors each update builds from its rollout buffer on ``device`` (default ``cpu``,
whose numbers are unchanged: every placement is then a no-op). What stays on the host:
the environment, the observations and the rollout buffer's storage (numpy arrays the
environment writes into in place), the safety filter, and action sampling (the logits
come back to the host and are sampled there with the method's host generators, so the
random streams are the same on every device). The tensors cross at the network boundary:
observations in, logits (and, for the filter, log-probabilities) out.

A cell's id and stored parameters never name the device (``bench run --device``,
docs/guide/speed.md "Accelerators"; decision record 0229).
May import: envs.errors (torch lazily).
"""
from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from envs.errors import BenchError

if TYPE_CHECKING:
    import torch

__all__ = ["CPU", "check_device", "host_tree", "module_device", "resolve_device"]

CPU = "cpu"  # the default device, whose numbers never change


def _available(kind: str, index: int | None) -> str | None:
    """None when a device of ``kind`` (and ``index``) can be used here, else why not."""
    import torch

    if kind == "cpu":
        return None
    if kind == "meta":
        return "the meta device holds no data; a run needs cpu or an accelerator"
    if kind == "cuda":
        if not torch.cuda.is_available():
            build = f"torch {torch.__version__}" + ("" if torch.version.cuda else ", a build without CUDA")
            return f"no CUDA device is available here ({build})"
        count = torch.cuda.device_count()
        if index is not None and index >= count:
            return f"CUDA device {index} does not exist ({count} visible)"
        return None
    backend = getattr(torch, kind, None)
    is_available: Callable[[], bool] | None = getattr(backend, "is_available", None)
    if kind == "mps":
        is_available = torch.backends.mps.is_available
    if is_available is None or not is_available():
        return f"no {kind} device is available here"
    return None


def resolve_device(name: Any = None, where: str = "device") -> torch.device:
    """The ``torch.device`` called ``name`` (None: cpu); BenchError naming ``where`` when the
    name is no torch device or no such device is available on this machine."""
    import torch

    if name is None:
        return torch.device(CPU)
    if isinstance(name, torch.device):
        device = name
    else:
        try:
            device = torch.device(str(name).strip())
        except (RuntimeError, ValueError):
            raise BenchError(f"{where} {str(name)!r}: not a torch device; use cpu, cuda or cuda:N") from None
    why = _available(device.type, device.index)
    if why is not None:
        raise BenchError(f"{where} {str(name)!r}: {why}; use --device cpu")
    return device


def check_device(name: str | None, where: str = "--device") -> str:
    """``resolve_device``'s check for a command line (no torch import when cpu or unset):
    the name as given, or BenchError."""
    if name is None or name.strip() == CPU:
        return CPU
    return str(resolve_device(name, where))


def module_device(module: torch.nn.Module) -> torch.device:
    """The device of a module's first parameter (or buffer); cpu for one with neither."""
    import torch

    for param in module.parameters():
        return param.device
    for buf in module.buffers():
        return buf.device
    return torch.device(CPU)


def host_tree(tree: Any) -> Any:
    """Every tensor of a nested dict / list / tuple moved to the host (a checkpoint of a
    device run loads on a machine without the device); other values as they are."""
    import torch

    if isinstance(tree, torch.Tensor):
        return tree.cpu()
    if isinstance(tree, dict):
        return {k: host_tree(v) for k, v in tree.items()}
    if isinstance(tree, list | tuple):
        return type(tree)(host_tree(v) for v in tree)
    return tree
