"""The contract every method implements, so the bench treats all of them alike.

A method is built from an environment config, its hyperparameters (a pydantic model,
``Params``) and a seed. It exposes:

* ``begin(batch, choice)`` -> a controller state for B episodes (recurrent states, loss
  processes, rollout storage when ``choice.training``); ``decide(batch, state, choice)`` ->
  a ``Decision`` for the current step, its controls picked by ``choice(logits)`` (argmax or
  a sample, algorithms/common/execution.py). The shared loops below drive these.
* ``run(batch, choice, observer)``: the shared episode loop; an ``observer`` (optional)
  is called once per step with a ``StepRecord`` (algorithms/common/observer.py: positions,
  controls proposed and executed, messages delivered, the filter's decisions) and changes
  no number. ``evaluate`` passes its ``observer`` on.
* ``evaluate(chunk, seed, execution, observer)`` -> one metric row per evaluation episode of that
  chunk in one execution mode (``argmax``, ``sample``, ``sample@T``; ``planner`` for a
  planner); every mode sees the same scenarios and loss draws; chunks are fixed-size, so
  evaluation fans out over workers and gives the same rows in any split.
* ``train_iteration()`` -> one update from ``batch_episodes`` fresh episodes; returns one
  row per episode (learned methods; a planner returns no rows and learns nothing).
* The inference-mode rule: rollouts (``begin``, ``decide``, ``observe`` inside ``evaluate`` and
  ``train_iteration``) run under ``torch.inference_mode()``, so nothing they compute carries a
  gradient. Store the inputs (observations, masks, sampled actions) and recompute the
  log-probabilities in ``update``; a backward pass through a rollout tensor raises
  ``InferenceModeError`` saying so.
* ``device``: the torch device of the networks (``Method(..., device="cuda")``; default
  cpu), an execution choice like the number of workers, never a parameter; the
  environment, observations, rollout storage, filter and sampling stay on the host
  (algorithms/common/device.py). A learned method places its modules with
  ``place_modules()`` and moves what it builds from host arrays to ``self.device``.
* ``state_dict()`` / ``load_state_dict()`` -> tensors and plain data only (parameters,
  optimizer states, RNG states, counters), loadable with ``torch.load(weights_only=True)``;
  a run resumed from it continues exactly as an uninterrupted one.
"""
from __future__ import annotations

import time
import warnings
from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from algorithms.common.allocator import tune_allocator
from algorithms.common.device import CPU, host_tree, resolve_device
from algorithms.common.episodes import (
    EVAL_STREAM,
    TRAIN_STREAM,
    Decision,
    EpisodeBatch,
    EpisodeStats,
    batch_rng,
)
from algorithms.common.execution import (
    ARGMAX,
    DEFAULT_TEMPERATURES,
    PLANNER,
    ActionChoice,
    execution_modes,
    parse_execution,
    sample_categorical,
)
from algorithms.common.observer import Observer, Snapshot, step_record
from algorithms.common.precision import FP32, Precision, tag
from algorithms.presets import Preset
from envs.config import EnvConfig, format_validation_error
from envs.core import StepResult
from envs.errors import BenchError
from envs.layouts import load_layout

if TYPE_CHECKING:  # imported where it is used: the registry, cells and the CLI load this without torch
    import torch

# The whole Method API from one import (docs/api.md; docs/guide/tutorial.md builds a method on it).
__all__ = ["BASELINE", "REFERENCE", "UNRANKED", "ActionChoice", "Decision", "EpisodeBatch", "InferenceModeError",
           "LearnedParams", "Method", "MethodParams", "StepResult", "masked_logits", "sample_categorical",
           "shared_learned_params"]

UNRANKED = 100  # legend_rank of a method that declares none: after the paper's methods
# ``Method.paper_role``: the paper's own method, one of the baselines it is compared with, or
# neither ("", every method a user brings), which the claims page judges against each baseline.
REFERENCE, BASELINE = "reference", "baseline"


class MethodParams(BaseModel):
    """Hyperparameters shared by every method; subclasses add their own fields."""

    model_config = ConfigDict(frozen=True, extra="forbid")
    # Parameters added after cells were stored whose default is the behaviour those cells ran
    # with: a stored row without one is no change while it is at its default (decision 0216).
    added_later: ClassVar[tuple[str, ...]] = ()

    batch_episodes: int = Field(8, ge=1, description="episodes per training update (batched in one process)")
    eval_chunk: int = Field(10, ge=1, description="evaluation episodes per chunk (the unit of fan-out)")

    @model_validator(mode="before")
    @classmethod
    def _no_execution(cls, data: Any) -> Any:
        """The former ``execution`` parameter: every mode is now evaluated (say so clearly)."""
        if isinstance(data, Mapping) and "execution" in data:
            raise ValueError("execution is not a method parameter: every learned cell is evaluated "
                             "in argmax, sample and sample@T (cell field eval_temperatures); pick one "
                             "mode with `bench eval --execution`")
        return data


class LearnedParams(MethodParams):
    """Hyperparameters every learned method shares, with one set of defaults (SPEC 3
    "Equal footing": identical defaults; chosen by the measurement in
    docs/decisions/0126). Method-specific fields stay in each method's subclass."""

    added_later: ClassVar[tuple[str, ...]] = (
        "protocol", "ppo_epochs", "ppo_minibatches", "ppo_clip", "ppo_lr", "gamma", "gae_lambda", "credit",
        "precision")

    hidden: int = Field(64, ge=4, description="hidden width of the method's policy networks")
    critic_hidden: int = Field(64, ge=4, description="width of the centralized critic V_omega")
    lr: float = Field(3e-3, gt=0, description="learning rate of the policy (Adam unless the method says otherwise)")
    critic_lr: float = Field(1e-3, gt=0, description="Adam learning rate of the critic V_omega")
    entropy_coef: float = Field(0.01, ge=0, description="entropy bonus per robot-step (0 = the paper's loss)")
    max_grad_norm: float = Field(10.0, gt=0, description="global gradient-norm clip of every optimizer step")
    normalize_advantage: bool = Field(True, description="divide the team advantage by its batch RMS")
    # The training protocol (algorithms/common/ppo.py, docs/training-protocols.md); the ppo_*
    # fields act only under protocol="mappo".
    protocol: Literal["paper", "mappo"] = Field(
        "paper", description="paper: the paper's trainer; mappo: GAE, clipped surrogate, value normalization")
    ppo_epochs: int = Field(1, ge=1, description="mappo: epochs over each batch (actor and critic)")
    ppo_minibatches: int = Field(4, ge=1, description="mappo: minibatches per epoch")
    ppo_clip: float = Field(0.2, gt=0, description="mappo: clip range of the probability ratio")
    ppo_lr: float = Field(5e-4, gt=0, description="mappo: Adam rate of the policy (lr is the paper's)")
    gamma: float = Field(0.99, gt=0, le=1, description="mappo: discount of the GAE returns")
    gae_lambda: float = Field(0.95, ge=0, le=1, description="mappo: GAE lambda")
    credit: Literal["robot", "team"] = Field(
        "robot", description="mappo: each robot's advantage from its own reward terms, or the team's")
    # The compute precision of the updates' network forward passes (algorithms/common/precision.py,
    # decision 0241); bf16 changes the numbers and stays out of published runs until its
    # equivalence check passes (decision 0240).
    precision: Precision = Field(
        FP32, description="fp32, or bf16: the updates' network forward passes under torch.autocast (bfloat16); "
                          "not in published runs until its equivalence check passes (docs/decisions/0240)")


def shared_learned_params() -> dict[str, tuple[Any, str]]:
    """Every parameter ``LearnedParams`` shares among learned methods: name -> (default,
    description). A method's ``Params`` that redefines one gets a warning (``Method``)."""
    return {name: (f.default, f.description or "") for name, f in LearnedParams.model_fields.items()
            if name not in MethodParams.model_fields}


class InferenceModeError(RuntimeError):
    """``update()`` backpropagated through a tensor made during the rollout: rollouts run
    under ``torch.inference_mode()``, so they never carry a gradient."""


# The messages torch gives for a backward pass through rollout (inference-mode) tensors.
_NO_GRAD_MESSAGES = ("does not require grad", "Inference tensors", "inference tensor")


def _warn_shadowed(method: type[Method], params: type[MethodParams]) -> None:
    """Warn when a method's own ``Params`` redefines a shared learned-method parameter
    with another default (the comparison is then not on equal footing, decisions/0126)."""
    if not issubclass(params, LearnedParams):
        return
    shared = LearnedParams.model_fields
    own = {name for k in params.__mro__ if isinstance(k, type) and issubclass(k, LearnedParams)
           and k is not LearnedParams for name in k.__dict__.get("__annotations__", {})}
    for name in sorted(own & set(shared) - set(MethodParams.model_fields)):
        default, base = params.model_fields[name].default, shared[name].default
        if default != base:
            warnings.warn(f"{method.__module__}.{method.__qualname__}: Params redefines the shared learned-method "
                          f"parameter {name!r} (default {default!r}, shared {base!r}); every learned method starts "
                          f"from the shared defaults (docs/extending.md, 'Shared parameters'): drop the field, or "
                          "keep it and say why", UserWarning, stacklevel=3)


class Method(ABC):
    """Base class of all methods; see the module docstring for the contract.

    Besides ``Params``, a method declares what the harness needs to know of it, so that no
    module outside its own names it (docs/extending.md): ``learned`` (False: a planner,
    evaluated in mode ``planner`` and never trained), ``safety_filter_default`` (a cell's
    ``safety_filter`` when the cell leaves it unset), ``payload_model`` (how the scalars it
    sends per step are counted, shown by ``bench methods``; ``payload_not_modelled``: True when
    ``Decision.payload`` is NaN every step, a method with no channel to count), ``display_name`` and ``color``
    (legend label and hex colour in every report figure; default: the name, grey),
    ``line_style`` and
    ``legend_rank`` (order in legends and tables; default after the built-ins), and
    ``paper_role`` (``REFERENCE`` for the paper's method, ``BASELINE`` for a baseline it is
    compared with; "" for any other method, which the claims page checks for being above
    each baseline of the run). ``presets`` names sets of its parameters that a grid file
    selects with ``preset = "NAME"`` (algorithms/presets.py; "paper", the defaults, is implicit).
    """

    name: ClassVar[str]
    learned: ClassVar[bool] = True
    Params: ClassVar[type[MethodParams]] = MethodParams
    safety_filter_default: ClassVar[bool] = False
    payload_model: ClassVar[str] = "scalars the method reports in Decision.payload each step"
    payload_not_modelled: ClassVar[bool] = False  # True: Decision.payload is NaN (a centralized planner)
    display_name: ClassVar[str] = ""
    color: ClassVar[str] = "#4d4d4d"
    line_style: ClassVar[str] = "-"  # matplotlib line style, so lines stay apart in greyscale
    legend_rank: ClassVar[int] = UNRANKED  # position in legends and tables (lower first)
    paper_role: ClassVar[str] = ""  # REFERENCE, BASELINE or "" (a method of your own)
    # Named presets of its parameters beside the implicit "paper" (algorithms/presets.py)
    presets: ClassVar[Mapping[str, Preset]] = {}

    @classmethod
    def label(cls) -> str:
        """The method's name in legends and tables (``display_name``, else ``name``)."""
        return cls.display_name or cls.name

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        params = cls.__dict__.get("Params")
        if isinstance(params, type) and not cls.__module__.startswith("algorithms."):
            _warn_shadowed(cls, params)  # a plugin's Params (the built-ins' are checked by their tests)

    def __init__(self, env: EnvConfig, params: Mapping[str, Any] | None = None, seed: int = 0,
                 device: Any = None) -> None:
        self.env = env
        self.params = self.parse_params(params or {})
        self.seed = int(seed)
        self.layout = load_layout(env.layout)
        import torch

        # The networks' device (algorithms/common/device.py): an execution choice, no parameter.
        self.device = resolve_device(device)

        self.iterations = 0  # training updates done
        self.episodes_done = 0
        torch.manual_seed(self.seed)  # initial weights: a pure function of the seed
        self.torch_gen = torch.Generator().manual_seed(self.seed + 1)  # training action samples
        tune_allocator()  # large update tensors reuse heap memory (allocation only)

    @classmethod
    def parse_params(cls, params: Mapping[str, Any]) -> MethodParams:
        try:
            return cls.Params(**dict(params))
        except ValidationError as exc:
            raise BenchError(format_validation_error(f"{cls.name} parameters", exc)) from None

    # ------------------------------------------------------------- controller
    @abstractmethod
    def begin(self, batch: EpisodeBatch, choice: ActionChoice) -> Any:
        """Controller state for the episodes of ``batch`` (called once, before step 0)."""

    @abstractmethod
    def decide(self, batch: EpisodeBatch, state: Any, choice: ActionChoice) -> Decision:
        """Controls for the current step of every episode of ``batch``, picked by ``choice``."""

    def observe(self, batch: EpisodeBatch, state: Any, result: Any) -> None:
        """Hook after each environment step (training methods store rewards here)."""
        return None

    # ------------------------------------------------------------------ loops
    def run(self, batch: EpisodeBatch, choice: ActionChoice, observer: Observer | None = None,
            ) -> tuple[Any, list[dict[str, Any]]]:
        """Run every episode of ``batch`` to its end; returns (state, metric rows).
        ``observer`` (optional) receives a ``StepRecord`` after every step."""
        core = batch.core
        stats = EpisodeStats(core.batch, core.n, self.env.d_m, lifelong=core.lifelong)
        state = self.begin(batch, choice)
        try:
            while batch.running:
                running = ~core.ended
                t, before = core.t, None if observer is None else Snapshot.of(core)
                dec = self.decide(batch, state, choice)
                self._check_payload(dec.payload)
                res = core.step(dec.actions)
                stats.add(running, res, dec)
                self.observe(batch, state, res)
                if observer is not None and before is not None:
                    observer(step_record(t, running, before, dec, res, core))
        except BenchError as exc:  # a bad action or payload: name the method that decided it
            raise BenchError(f"method {self.name}: {exc}") from None
        return state, stats.finish(core.done)

    def _check_payload(self, payload: np.ndarray | float) -> None:
        """BenchError unless ``payload`` is finite, or NaN throughout for a method whose
        payload is not modelled (``payload_not_modelled``): an inf or a stray NaN would be
        stored as NaN without a word (D16)."""
        p = np.asarray(payload, dtype=np.float64)
        if np.isfinite(p).all() or (self.payload_not_modelled and np.isnan(p).all()):
            return
        raise BenchError(f"Decision.payload holds {p[~np.isfinite(p)].flat[0]}: it counts the scalars sent this "
                         "step, a finite number (per episode or one for all)")

    @classmethod
    def execution_modes(cls, temperatures: Iterable[float] = DEFAULT_TEMPERATURES) -> tuple[str, ...]:
        """This method's evaluation modes: argmax, sample, sample@T (learned) or planner."""
        return execution_modes(cls.learned, temperatures)

    def execution_choice(self, execution: str | None, seed: int, chunk: int) -> ActionChoice:
        """The ``ActionChoice`` of mode ``execution`` (None: argmax, or planner) for a chunk;
        BenchError for a mode this method does not have."""
        name = execution if execution is not None else (ARGMAX if self.learned else PLANNER)
        mode = parse_execution(name, where=f"{self.name} execution")
        if (mode.name == PLANNER) == self.learned:
            allowed = "argmax, sample or sample@T" if self.learned else "planner"
            raise BenchError(f"{self.name} execution: mode {mode.name!r} does not apply to "
                             f"{'a learned method' if self.learned else 'a planner'}; use {allowed}")
        return ActionChoice.evaluate(mode.name, seed, chunk)

    def evaluate(self, chunk: int, seed: int | None = None, execution: str | None = None,
                 observer: Observer | None = None) -> list[dict[str, Any]]:
        """Rows of evaluation chunk ``chunk`` (episodes chunk*eval_chunk + k) in mode
        ``execution`` (default argmax, planner for a planner); each row names its mode
        (``execution``) and its scenario (``scenario``, a hash of starts and goals).
        ``observer`` sees every step of the chunk's batch (see ``run``)."""
        import torch

        size = self.params.eval_chunk
        seed = self.seed if seed is None else int(seed)
        choice = self.execution_choice(execution, seed, chunk)
        batch = EpisodeBatch(self.env, size, batch_rng(seed, EVAL_STREAM, chunk), self.layout)
        scenarios = batch.scenario_hashes()
        with torch.inference_mode():
            _, rows = self.run(batch, choice, observer)
        for k, row in enumerate(rows):
            row["episode"] = chunk * size + k
            row["execution"] = choice.name
            row["scenario"] = scenarios[k]
        return rows

    def train_iteration(self) -> list[dict[str, float]]:
        """One update from ``batch_episodes`` fresh episodes; rows carry the losses."""
        if not self.learned:
            return []
        import torch

        t0 = time.perf_counter()
        with torch.inference_mode():
            state, rows = self.run(self.train_batch(), ActionChoice.train(self.torch_gen))
        return self.finish_iteration(rows, self.checked_update(state), time.perf_counter() - t0)

    def checked_update(self, state: Any) -> dict[str, float]:
        """``update(state)``, with torch's error for a backward pass through rollout tensors
        (made under ``torch.inference_mode()``) turned into one that says what to do."""
        try:
            return self.update(state)
        except RuntimeError as exc:
            text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            if not any(m in text for m in _NO_GRAD_MESSAGES):
                raise
            raise InferenceModeError(
                f"{self.name}.update(): {text}. Rollouts (begin/decide/observe) run under torch.inference_mode(), "
                "so nothing they compute carries a gradient: store the inputs there (observations, masks, actions) "
                "and recompute the log-probabilities inside update() (docs/guide/tutorial.md, step 4)") from exc

    def train_batch(self) -> EpisodeBatch:
        """The episodes of the next training update (scenarios and loss streams from the
        cell seed and the update's index)."""
        rng = batch_rng(self.seed, TRAIN_STREAM, self.iterations)
        return EpisodeBatch(self.env, self.params.batch_episodes, rng, self.layout)

    def finish_iteration(self, rows: list[dict[str, Any]], losses: dict[str, float],
                         wall_s: float) -> list[dict[str, Any]]:
        """Number the update's episode rows, attach its losses and wall time per episode,
        and count the update."""
        wall = wall_s / len(rows)
        for k, row in enumerate(rows):
            row.update(losses)
            row["episode"] = self.episodes_done + k
            row["wall_s"] = wall
        self.iterations += 1
        self.episodes_done += len(rows)
        return rows

    @classmethod
    def stackable(cls, params: Mapping[str, Any]) -> bool:
        """Whether cells of this method with these parameters can train seed-stacked."""
        return False

    @classmethod
    def stack_view(cls, methods: Sequence[Method]) -> Method:
        """A method whose rollout runs the training episodes of ``methods`` (cells that
        differ only in their seed) as one batch (``algorithms/common/seed_stack.py``);
        methods that do not support it raise NotImplementedError."""
        raise NotImplementedError(f"{cls.name} does not stack seeds")

    def load_stack(self, methods: Sequence[Method]) -> None:
        """Copy the current parameters of ``methods`` into this stack view."""
        raise NotImplementedError(f"{self.name} does not stack seeds")

    def update(self, state: Any) -> dict[str, float]:
        """Gradient step(s) from a finished training batch; returns named losses."""
        raise NotImplementedError(f"{self.name} does not learn")

    # ------------------------------------------------------------ checkpoints
    def modules(self) -> dict[str, torch.nn.Module | torch.optim.Optimizer]:
        """Named modules and optimizers whose state is checkpointed."""
        return {}

    def place_modules(self) -> None:
        """Move the networks of ``modules()`` to ``self.device`` (a learned method calls it
        at the end of ``__init__``; nothing moves on the cpu). Optimizers made before keep
        their parameters: ``Module.to`` moves them in place. The networks and optimizers
        are tagged with the ``precision`` parameter, which the update code reads
        (algorithms/common/precision.py; fp32 tags nothing)."""
        tag(self.modules().values(), getattr(self.params, "precision", FP32))
        if self.device.type == CPU:
            return
        import torch

        for mod in self.modules().values():
            if isinstance(mod, torch.nn.Module):
                mod.to(self.device)

    def state_dict(self) -> dict[str, Any]:
        """Counters, RNG states and every module's and optimizer's state, on the host (a
        device run's checkpoint loads anywhere; ``load_state_dict`` moves it back)."""
        import torch

        out: dict[str, Any] = {
            "iterations": self.iterations,
            "episodes_done": self.episodes_done,
            "torch_gen": self.torch_gen.get_state(),
            "torch_global": torch.get_rng_state(),
        }
        for key, mod in self.modules().items():
            out[key] = mod.state_dict()
        return out if self.device.type == CPU else host_tree(out)

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        import torch

        self.iterations = int(state["iterations"])
        self.episodes_done = int(state["episodes_done"])
        self.torch_gen.set_state(state["torch_gen"])
        torch.set_rng_state(state["torch_global"])
        for key, mod in self.modules().items():
            mod.load_state_dict(state[key])


def masked_logits(logits: torch.Tensor, mask: np.ndarray | torch.Tensor) -> torch.Tensor:
    """Set logits of disallowed actions (mask False) to a large negative number."""
    import torch

    m = torch.as_tensor(mask, dtype=torch.bool, device=logits.device)
    return logits.masked_fill(~m, -1e9)
