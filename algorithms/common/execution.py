"""Execution modes: how a method picks its controls from its policy's logits.

Every learned cell is evaluated in every mode on the same scenarios (docs/decisions/0068):

* ``argmax``: the most probable action at every level (the paper's execution, Sec. III-B
  "a deterministic reference can be selected" and eq:local_deterministic_control);
* ``sample``: a sample from the policy, softmax(logits) (temperature T = 1, the training
  distribution);
* ``sample@T``: a sample from softmax(logits / T) (tempered; T = 0.5 by default, the cell
  field ``eval_temperatures``).

A planner (PIBT) has one mode, ``planner``: it plans, it has no policy to sample from.
Training always samples at T = 1 from the method's own training stream.

Streams (SPEC 7 "Seeds"): an evaluation chunk draws its scenarios and channel losses from
``batch_rng(seed, EVAL_STREAM, chunk)`` and its action samples from a separate generator,
``action_generator(seed, chunk)`` (``ACTION_STREAM``), so a mode never shifts the scenario or
loss stream: episode k of chunk c has the same starts, goals and loss draws in every mode.
The sampled modes share the action seed (common random numbers).
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from envs.errors import BenchError

if TYPE_CHECKING:  # imported where it is used: naming a mode or checking a cell needs no torch
    import torch

__all__ = ["ACTION_STREAM", "ARGMAX", "ARGMAX_CHOICE", "DEFAULT_TEMPERATURES", "HEADLINE", "PLANNER", "SAMPLE", "TRAIN",
           "ActionChoice", "ExecutionMode", "action_generator", "check_temperatures", "execution_modes",
           "learned_modes", "mode_name", "multinomial_one", "parse_execution", "sample_categorical"]

# Execution mode names (the training rollouts' is ``train``).
ARGMAX, SAMPLE, PLANNER, TRAIN = "argmax", "sample", "planner", "train"
HEADLINE = ARGMAX  # the mode headline numbers quote (docs/decisions/0069: the paper's execution)
DEFAULT_TEMPERATURES = (0.5,)  # the sample@T modes every learned method is evaluated in
ACTION_STREAM = 2  # after TRAIN_STREAM = 0 and EVAL_STREAM = 1 (algorithms/common/episodes.py)


@dataclass(frozen=True)
class ExecutionMode:
    """A named way of picking controls: ``temperature`` None is argmax (or a planner)."""

    name: str
    temperature: float | None

    @property
    def greedy(self) -> bool:
        return self.temperature is None


def mode_name(temperature: float) -> str:
    """'sample' for T = 1, else 'sample@T' (T printed with ``:g``, e.g. 'sample@0.5')."""
    return SAMPLE if float(temperature) == 1.0 else f"{SAMPLE}@{float(temperature):g}"


def parse_execution(name: str, where: str = "execution") -> ExecutionMode:
    """The mode called ``name`` ('argmax', 'sample', 'sample@T', 'planner'); BenchError
    naming ``where`` otherwise. 'sample@1' is 'sample'."""
    text = str(name).strip()
    if text in (ARGMAX, PLANNER):
        return ExecutionMode(text, None)
    if text == SAMPLE:
        return ExecutionMode(SAMPLE, 1.0)
    if text.startswith(f"{SAMPLE}@"):
        try:
            t = float(text[len(SAMPLE) + 1:])
        except ValueError:
            t = math.nan
        if math.isfinite(t) and t > 0:
            return ExecutionMode(mode_name(t), t)
    raise BenchError(f"{where}: unknown execution mode {text!r}; choose argmax, sample, "
                     "sample@T (a temperature T > 0, e.g. sample@0.5) or planner (PIBT)")


def check_temperatures(temperatures: Iterable[float]) -> tuple[float, ...]:
    """Validated sampling temperatures of the tempered modes: finite, > 0, not 1 (that is
    ``sample``), no duplicates; returned in descending order (canonical, for cell ids)."""
    temps = tuple(float(t) for t in temperatures)
    for t in temps:
        if not math.isfinite(t) or t <= 0:
            raise ValueError(f"temperature {t} must be a finite number > 0")
        if t == 1.0:
            raise ValueError("temperature 1 is the 'sample' mode, always evaluated; list only T != 1")
    if len(set(temps)) != len(temps):
        raise ValueError(f"duplicate temperature in {list(temps)}")
    return tuple(sorted(temps, reverse=True))


def learned_modes(temperatures: Iterable[float] = DEFAULT_TEMPERATURES) -> tuple[str, ...]:
    """The evaluation modes of a learned cell: argmax, sample, then sample@T per T."""
    return (ARGMAX, SAMPLE, *(mode_name(t) for t in check_temperatures(temperatures)))


def execution_modes(learned: bool, temperatures: Iterable[float] = DEFAULT_TEMPERATURES) -> tuple[str, ...]:
    """Every evaluation mode of a cell: ``learned_modes`` or ('planner',)."""
    return learned_modes(temperatures) if learned else (PLANNER,)


def sample_categorical(logits: torch.Tensor, temperature: float | None,
                       gen: torch.Generator | None) -> torch.Tensor:
    """Argmax (``temperature`` None) or one sample from softmax(logits / T) per row.

    logits (..., K) -> (...) int64 on the host. Masked logits (-1e9) stay impossible at any
    T > 0. Logits on an accelerator come to the host first: the draws come from the host
    generator ``gen`` on every device (algorithms/common/device.py).
    """
    logits = logits.cpu()  # no copy on the cpu
    if temperature is None:
        return logits.argmax(dim=-1)
    import torch

    flat = logits.reshape(-1, logits.shape[-1]).double()
    if float(temperature) != 1.0:  # x / 1.0 is x: skipped at T = 1 (training, 'sample')
        flat = flat / float(temperature)
    probs = torch.softmax(flat, dim=-1)
    return multinomial_one(probs, gen).reshape(logits.shape[:-1])


def multinomial_one(probs: torch.Tensor, gen: torch.Generator | None) -> torch.Tensor:
    """``torch.multinomial(probs, 1, generator=gen)`` for (R, K) probabilities, as torch's
    CPU kernel computes it (argmax of p / q with q ~ Exp(1) drawn by ``exponential_`` from
    ``gen``): the same samples and the same generator state afterwards, with one finiteness
    check instead of torch's several validity reductions (tests/algorithms/test_baseline_fast_paths.py)."""
    import torch

    q = torch.empty_like(probs).exponential_(1, generator=gen)
    torch.div(probs, q, out=q)
    if not bool(torch.isfinite(probs.sum())):
        raise RuntimeError("probability tensor contains either `inf`, `nan` or element < 0")
    return q.argmax(dim=-1, keepdim=True)


def action_generator(seed: int, chunk: int) -> torch.Generator:
    """The action-sampling generator of evaluation chunk ``chunk`` of a cell seed; a stream
    of its own (``ACTION_STREAM``), never the scenario/loss stream of the chunk."""
    import torch

    state = np.random.SeedSequence([int(seed), ACTION_STREAM, int(chunk)]).generate_state(2, np.uint32)
    return torch.Generator().manual_seed(int(state[0]) << 31 | int(state[1]) >> 1)


@dataclass(frozen=True)
class ActionChoice:
    """How the controls of one ``Method.run`` are picked: its mode, the generator samples
    come from, and whether the run is a training rollout (stored for an update)."""

    mode: ExecutionMode
    gen: torch.Generator | None = None
    training: bool = False

    def __call__(self, logits: torch.Tensor) -> torch.Tensor:
        """(..., K) logits -> (...) int64 controls in this mode."""
        return sample_categorical(logits, self.mode.temperature, self.gen)

    @property
    def name(self) -> str:
        return self.mode.name

    @classmethod
    def train(cls, gen: torch.Generator) -> ActionChoice:
        """Training rollouts: samples at T = 1 from the method's training stream."""
        return cls(ExecutionMode(TRAIN, 1.0), gen, training=True)

    @classmethod
    def evaluate(cls, name: str, seed: int = 0, chunk: int = 0) -> ActionChoice:
        """Evaluation in mode ``name`` for chunk ``chunk`` of a cell seed (see the module)."""
        mode = parse_execution(name)
        return cls(mode, None if mode.greedy else action_generator(seed, chunk))


# Argmax evaluation: no generator needed.
ARGMAX_CHOICE = ActionChoice(ExecutionMode(ARGMAX, None))
