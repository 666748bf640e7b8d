"""``linear``: a learned per-robot policy, logits linear in three features of each action.

For robot i and action a (0 Up, 1 Down, 2 Left, 3 Right, 4 Wait), with c = move(p_i, a):

    logit(a) = w . [D(p_i, g_i) - D(c, g_i), robot on c now, a blocked by a shelf] + b_a

Trained by REINFORCE on the team reward: the return-to-go G_t of each episode minus the
batch mean at step t as the baseline, one Adam step per update. Parameters are shared by
all robots, so any N uses the same policy. No messages are sent (payload 0).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch
from pydantic import Field
from torch import nn

from algorithms.base import Method, MethodParams
from algorithms.common.episodes import Decision, EpisodeBatch
from algorithms.common.execution import ActionChoice
from envs.actions import N_ACTIONS, WAIT
from envs.core import StepResult

N_FEATURES = 3


class LinearParams(MethodParams):
    lr: float = Field(0.05, gt=0, description="Adam learning rate")
    gamma: float = Field(1.0, gt=0, le=1, description="discount of the return-to-go")


@dataclass
class Rollout:
    """Per step of a training batch: features (B, N, 5, 3), actions (B, N), robot-steps
    that count (B, N), team rewards (B,)."""

    rng: np.random.Generator
    feats: list[np.ndarray] = field(default_factory=list)
    actions: list[np.ndarray] = field(default_factory=list)
    active: list[np.ndarray] = field(default_factory=list)
    rewards: list[np.ndarray] = field(default_factory=list)


class LinearPolicy(Method):
    name = "linear"
    display_name = "Linear (example)"
    color = "#ca9161"
    payload_model = "none: no messages (0 scalars sent)"
    Params = LinearParams

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)  # seeds torch: the initial weights follow the cell seed
        self.policy = nn.Linear(N_FEATURES, 1)
        self.bias = nn.Parameter(torch.zeros(N_ACTIONS))
        self.net = nn.ModuleDict({"w": self.policy, "b": nn.ParameterList([self.bias])})
        self.optimizer = torch.optim.Adam(self.net.parameters(), lr=self.params.lr)

    def modules(self) -> dict[str, nn.Module | torch.optim.Optimizer]:
        return {"policy": self.net, "optimizer": self.optimizer}

    def features(self, batch: EpisodeBatch) -> np.ndarray:
        core = batch.core
        nxt = self.layout.next_cell[core.pos]  # (B, N, 5)
        progress = core.dist[..., None] - core.distances_to_goal(nxt)
        occupied = np.zeros((core.batch, self.layout.n_free), dtype=bool)
        rows, robots = np.nonzero(core.occupying)
        occupied[rows, core.pos[rows, robots]] = True
        on_target = occupied[np.arange(core.batch)[:, None, None], nxt]
        on_target[..., WAIT] = False
        blocked = nxt == core.pos[..., None]
        blocked[..., WAIT] = False
        return np.stack([progress, on_target, blocked], axis=-1).astype(np.float32)

    def logits(self, feats: torch.Tensor) -> torch.Tensor:
        return self.policy(feats).squeeze(-1) + self.bias

    def begin(self, batch: EpisodeBatch, choice: ActionChoice) -> Rollout:
        return Rollout(batch.rng)

    def decide(self, batch: EpisodeBatch, state: Rollout, choice: ActionChoice) -> Decision:
        feats = self.features(batch)
        with torch.no_grad():
            actions = choice(self.logits(torch.from_numpy(feats))).numpy().astype(np.int64)
        core = batch.core
        actions[core.done | core.ended[:, None]] = WAIT
        if choice.training:
            state.feats.append(feats)
            state.actions.append(actions)
        return Decision(actions=actions, payload=0.0)

    def observe(self, batch: EpisodeBatch, state: Rollout, result: StepResult) -> None:
        if state.feats and len(state.rewards) < len(state.feats):
            state.active.append(result.active)
            state.rewards.append(result.reward)

    def update(self, state: Rollout) -> dict[str, float]:
        rewards = np.stack(state.rewards)  # (T, B)
        returns = np.zeros_like(rewards)
        acc = np.zeros(rewards.shape[1])
        for t in range(len(rewards) - 1, -1, -1):
            acc = rewards[t] + self.params.gamma * acc
            returns[t] = acc
        adv = torch.from_numpy(returns - returns.mean(axis=1, keepdims=True)).float()  # (T, B)
        feats = torch.from_numpy(np.stack(state.feats))  # (T, B, N, 5, 3)
        actions = torch.from_numpy(np.stack(state.actions))  # (T, B, N)
        active = torch.from_numpy(np.stack(state.active)).float()  # (T, B, N)
        logp = torch.log_softmax(self.logits(feats), dim=-1).gather(-1, actions[..., None]).squeeze(-1)
        loss = -(adv[..., None] * logp * active).sum() / active.sum().clamp(min=1.0)
        self.optimizer.zero_grad()
        loss.backward()
        self.optimizer.step()
        return {"policy_loss": loss.item()}
