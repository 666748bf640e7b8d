"""The learned methods' compute precision: ``precision = "bf16"`` runs their updates' network
forward passes under ``torch.autocast(dtype=torch.bfloat16)`` (issue 48 item 4;
docs/decisions/0241).

A method parameter (``LearnedParams.precision``, default ``"fp32"``), because it changes the
numbers (unlike the device, decision 0229): a cell that sets it has its own cell id, its
resolved parameters (``params_json``) say it, and the reports show such cells as a variant
of their method (``precision=bf16``). ``"fp32"`` is the behaviour of every cell trained
before the parameter existed (``added_later``, decision 0216), bit for bit.

``Method.place_modules`` tags the method's networks and optimizers with the parameter
(``tag``); the update code reads the tag of what it is handed (``autocast``), so every
method's update, seed-stacked or not, gets it without passing it along. Where autocast
applies (decision 0241): the forward passes of the critics and of the policies inside an
update (paper and mappo protocols), the values and log-probabilities brought back to
float32 before any loss; parameters, gradients, optimizer states and losses stay float32
(autocast semantics). The rollout, the GRU predictor's update and the decentralized and
IC3Net paper-protocol actor updates stay float32.
May import: algorithms.common.device (torch lazily).
"""
from __future__ import annotations

import contextlib
from collections.abc import Iterable, Iterator
from typing import TYPE_CHECKING, Any, Literal

if TYPE_CHECKING:
    import torch

__all__ = ["BF16", "FP32", "PRECISIONS", "Precision", "autocast", "precision_of", "tag", "to_fp32"]

Precision = Literal["fp32", "bf16"]
FP32: Precision = "fp32"
BF16: Precision = "bf16"
PRECISIONS: tuple[str, ...] = (FP32, BF16)
_TAG = "_bench_precision"  # attribute on a tagged module or optimizer


def tag(objects: Iterable[Any], precision: str) -> None:
    """Mark ``objects`` (modules, optimizers) with ``precision``; fp32 marks nothing."""
    if precision == FP32:
        return
    if precision not in PRECISIONS:
        raise ValueError(f"precision {precision!r}: use one of {', '.join(PRECISIONS)}")
    for obj in objects:
        setattr(obj, _TAG, precision)


def precision_of(obj: Any) -> str:
    """The precision ``obj`` was tagged with (fp32 when untagged)."""
    return str(getattr(obj, _TAG, FP32))


def _device_type(obj: Any) -> str:
    import torch

    if isinstance(obj, torch.optim.Optimizer):
        for group in obj.param_groups:
            for param in group["params"]:
                return str(param.device.type)
        return "cpu"
    from algorithms.common.device import module_device

    return module_device(obj).type


@contextlib.contextmanager
def autocast(owner: torch.nn.Module | torch.optim.Optimizer) -> Iterator[None]:
    """``torch.autocast(bfloat16)`` on ``owner``'s device when it is tagged bf16; nothing
    (not even an autocast region) when it is fp32, so the default's numbers never change."""
    if precision_of(owner) != BF16:
        yield
        return
    import torch

    with torch.autocast(_device_type(owner), dtype=torch.bfloat16):
        yield


def to_fp32(tensor: torch.Tensor) -> torch.Tensor:
    """``tensor`` as float32 when autocast made it bfloat16; the tensor itself otherwise
    (no copy, no new graph node: the fp32 path is unchanged)."""
    import torch

    return tensor.float() if tensor.dtype == torch.bfloat16 else tensor
