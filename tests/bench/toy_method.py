"""A tiny learned Method for bench tests (fast, deterministic, with fault injection).

Per robot, logits over the 5 actions = bias[a] + beta * progress(a) (envs.observations
action_progress); REINFORCE on the team return with Adam. Its state_dict holds a
module and an optimizer, so checkpoint/resume is exercised like a real method.

Fault injection (test-only params; they do not change the numbers):
* ``die_at_iteration`` + ``marker``: at that training iteration, if ``marker`` does not
  exist, create it and SIGKILL the own process (a worker dying mid-cell, once);
* ``raise_at_iteration``: raise RuntimeError at that iteration (a failing cell);
* ``sleep_s``: sleep per training iteration (widens windows for kill tests).
"""
from __future__ import annotations

import os
import signal
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from algorithms.base import ActionChoice, Method, MethodParams, masked_logits
from algorithms.common.episodes import Decision, EpisodeBatch
from algorithms.common.trainer import mc_returns
from envs.observations import action_progress

TOY_PATH = "tests.bench.toy_method:ToyMethod"


class ToyParams(MethodParams):
    lr: float = 0.05
    die_at_iteration: int = -1
    marker: str = ""
    raise_at_iteration: int = -1
    sleep_s: float = 0.0


class ToyPolicy(torch.nn.Module):
    def __init__(self) -> None:
        super().__init__()
        self.bias = torch.nn.Parameter(torch.zeros(5))
        self.beta = torch.nn.Parameter(torch.ones(1))

    def forward(self, progress: torch.Tensor) -> torch.Tensor:
        return self.bias + self.beta * progress


class ToyMethod(Method):
    name = "toy"
    Params = ToyParams

    def __init__(self, env: Any, params: Any = None, seed: int = 0) -> None:
        super().__init__(env, params, seed)
        self.policy = ToyPolicy()
        self.opt = torch.optim.Adam(self.policy.parameters(), lr=self.params.lr)

    def modules(self) -> dict[str, Any]:
        return {"policy": self.policy, "opt": self.opt}

    def begin(self, batch: EpisodeBatch, choice: ActionChoice) -> dict[str, list[Any]]:
        return {"prog": [], "act": [], "rew": [], "run": []}

    def decide(self, batch: EpisodeBatch, state: dict[str, list[Any]], choice: ActionChoice) -> Decision:
        core = batch.core
        prog = torch.as_tensor(action_progress(core))
        mask = core.layout.move_valid[core.pos]
        logits = masked_logits(self.policy(prog), mask)
        actions = choice(logits).numpy()
        actions = np.where(core.done | core.ended[:, None], 4, actions)
        state["prog"].append(prog)
        state["act"].append(torch.as_tensor(actions))
        state["run"].append(torch.as_tensor(~core.ended))
        return Decision(actions=actions, payload=0.0)

    def observe(self, batch: EpisodeBatch, state: dict[str, list[Any]], result: Any) -> None:
        state["rew"].append(np.asarray(result.reward, dtype=np.float32))

    def train_iteration(self) -> list[dict[str, float]]:
        p = self.params
        if p.sleep_s:
            time.sleep(p.sleep_s)
        if self.iterations == p.raise_at_iteration:
            raise RuntimeError(f"toy failure at iteration {self.iterations}")
        if self.iterations == p.die_at_iteration and p.marker and not Path(p.marker).exists():
            Path(p.marker).write_text(str(os.getpid()))
            os.kill(os.getpid(), signal.SIGKILL)
        return super().train_iteration()

    def update(self, state: dict[str, list[Any]]) -> dict[str, float]:
        with torch.enable_grad():
            prog = torch.stack(state["prog"])  # (T, B, N, 5)
            act = torch.stack(state["act"])  # (T, B, N)
            run = torch.stack(state["run"]).float()  # (T, B)
            ret = mc_returns(np.stack(state["rew"]))  # (T, B)
            adv = (ret - ret.mean()) / (ret.std() + 1e-6)
            logp = torch.log_softmax(self.policy(prog), dim=-1).gather(-1, act[..., None]).squeeze(-1)
            loss = -(adv[..., None] * logp * run[..., None]).mean()
            self.opt.zero_grad()
            loss.backward()
            self.opt.step()
        return {"actor_loss": float(loss.detach())}


AGE_PROBE_PATH = "tests.bench.toy_method:AgeProbe"


class AgeProbe(ToyMethod):
    """The toy policy, plus a robot-to-robot channel it only listens to: each step's
    ``predictor_error`` column becomes the mean age (steps) of the messages its robots hold,
    so an episode's row says which delay its channel had (fixed delay d and no loss: exactly
    d; delay 0: 0)."""

    name = "ageprobe"

    def begin(self, batch: EpisodeBatch, choice: ActionChoice) -> dict[str, Any]:
        state: dict[str, Any] = dict(super().begin(batch, choice))
        state["channel"] = batch.open_channel("robots")
        return state

    def decide(self, batch: EpisodeBatch, state: dict[str, Any], choice: ActionChoice) -> Decision:
        decision = super().decide(batch, state, choice)
        channel = state["channel"]
        now = channel.step()
        if channel.sent_at is None:  # no delay: what arrives is this step's message, age 0
            held, age = now, np.zeros(now.shape)
        else:
            held = channel.sent_at >= 0
            age = np.where(held, channel.delay.t - 1 - channel.sent_at, 0)
        decision.pred_sq_err = age.sum(axis=(1, 2)).astype(np.float64)
        decision.pred_count = held.sum(axis=(1, 2)).astype(np.float64)
        return decision
