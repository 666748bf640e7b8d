"""What a method author meets first: ``choice()`` output is a valid ``Decision``,
a backward pass through rollout tensors names the inference-mode rule, and a plugin that
redefines a shared learned-method parameter is warned."""
from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
import torch
from torch import nn

from algorithms.base import (
    ActionChoice,
    Decision,
    EpisodeBatch,
    InferenceModeError,
    LearnedParams,
    Method,
    shared_learned_params,
)
from envs.config import EnvConfig

ENV = EnvConfig(n_robots=4, layout="tiny", horizon=6, groups=2, loss_p=0.3)


def test_decision_takes_the_tensor_choice_gives_as_a_numpy_array() -> None:
    actions = ActionChoice.evaluate("argmax")(torch.randn(3, 4, 5))
    dec = Decision(actions=actions)
    assert isinstance(dec.actions, np.ndarray) and dec.actions.dtype == np.int64
    assert np.array_equal(dec.actions, actions.numpy())


class KeepsLogProbs(Method):
    """Breaks the inference-mode rule: keeps log-probabilities from decide()."""

    name = "keeps-logp"

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.net = nn.Linear(1, 5)

    def begin(self, batch: EpisodeBatch, choice: ActionChoice) -> list[torch.Tensor]:
        return []

    def decide(self, batch: EpisodeBatch, state: list[torch.Tensor], choice: ActionChoice) -> Decision:
        logits = self.net(torch.ones(batch.core.pos.shape + (1,)))
        actions = choice(logits)
        state.append(torch.log_softmax(logits, -1).gather(-1, actions[..., None]).sum())
        return Decision(actions=actions)

    def update(self, state: list[torch.Tensor]) -> dict[str, float]:
        loss = -torch.stack(state).sum()
        loss.backward()
        return {"loss": float(loss)}


def test_backpropagating_through_a_rollout_names_the_inference_mode_rule() -> None:
    with pytest.raises(InferenceModeError, match=r"keeps-logp.update\(\).*inference_mode.*recompute"):
        KeepsLogProbs(ENV, {"batch_episodes": 1}).train_iteration()


def test_other_update_errors_pass_unchanged() -> None:
    class Fails(KeepsLogProbs):
        name = "fails"

        def update(self, state: list[torch.Tensor]) -> dict[str, float]:
            raise RuntimeError("something else")

    with pytest.raises(RuntimeError, match="^something else$"):
        Fails(ENV, {"batch_episodes": 1}).train_iteration()


def test_a_plugin_redefining_a_shared_parameter_is_warned() -> None:
    assert set(shared_learned_params()) >= {"hidden", "lr", "critic_lr", "entropy_coef"}

    class Wide(LearnedParams):
        hidden: int = 128

    with pytest.warns(UserWarning, match=r"'hidden' \(default 128, shared 64\)"):
        class WideMethod(KeepsLogProbs):
            name = "wide"
            Params = Wide


def test_own_parameters_and_unchanged_defaults_are_not_warned() -> None:
    class Own(LearnedParams):
        radius: int = 2
        lr: float = 3e-3  # redefined with the shared default: nothing changes

    with warnings.catch_warnings():
        warnings.simplefilter("error")

        class OwnMethod(KeepsLogProbs):
            name = "own"
            Params = Own


def test_extending_lists_every_shared_parameter_with_its_default() -> None:
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "extending.md").read_text(encoding="utf-8")
    listed = dict(re.findall(r"^\| `(\w+)` \| ([^|]+) \|", text, flags=re.M))
    for name, (default, _) in shared_learned_params().items():
        shown = {"True": "true", "False": "false"}.get(str(default), str(default))
        assert listed.get(name, "").strip() == shown, f"docs/extending.md: shared parameter {name} ({default})"
