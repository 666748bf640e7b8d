"""A plugin method that learns with the ``mappo`` protocol (docs/training-protocols.md).

``MappoWalker``: one small MLP shared by all robots on their local view (the public
per-robot observation), no messages. Its rollout keeps what the protocol needs (the
critic's inputs, each robot's reward terms, observations, masks, actions); its ``update``
hands the protocol two things: the critic half (``mappo_critic``) and a ``PPOBatch`` that
says which rows it learns from and how to recompute their log-probabilities. Put this folder
on PYTHONPATH and name it ``mappo_walker:MappoWalker`` in a grid file, with
``[base.params] protocol = "mappo"`` (its ``update`` refuses the paper protocol: it has no
paper-protocol trainer).
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from algorithms.base import ActionChoice, Decision, EpisodeBatch, LearnedParams, Method, StepResult, masked_logits
from algorithms.common.ppo import PPOBatch, RobotCritic, mappo_critic, ppo_actor_update, robot_rewards, update_generator
from algorithms.common.robot_obs import action_mask, local_view, local_view_size
from algorithms.common.trainer import RolloutBuffer, critic_shapes, store_critic_inputs
from envs.actions import N_ACTIONS
from envs.observations import PatchExtractor

RADIUS = 1


class WalkerState:
    def __init__(self, patch: PatchExtractor, buffer: RolloutBuffer | None, running: np.ndarray) -> None:
        self.patch, self.buffer, self.running = patch, buffer, running


class MappoWalker(Method):
    name = "mappo_walker"
    display_name = "MAPPO walker (example)"
    color = "#ca9161"
    payload_model = "none (0 scalars sent)"
    Params = LearnedParams
    params: LearnedParams

    def __init__(self, env, params=None, seed: int = 0) -> None:
        super().__init__(env, params, seed)
        p = self.params
        self.n_obs = local_view_size(RADIUS)
        self.actor = nn.Sequential(nn.Linear(self.n_obs, p.hidden), nn.ReLU(), nn.Linear(p.hidden, N_ACTIONS))
        self.critic = RobotCritic(p.critic_hidden)
        self.actor_opt = torch.optim.Adam(self.actor.parameters(), lr=p.ppo_lr)
        self.critic_opt = torch.optim.Adam(self.critic.parameters(), lr=p.critic_lr)

    def modules(self):
        return {"actor": self.actor, "critic": self.critic, "actor_opt": self.actor_opt, "critic_opt": self.critic_opt}

    def begin(self, batch: EpisodeBatch, choice: ActionChoice) -> WalkerState:
        b, n = batch.core.pos.shape
        buffer = None
        if choice.training:
            buffer = RolloutBuffer(self.env.horizon, b, {
                "obs": ((n, self.n_obs), np.float32), "mask": ((n, N_ACTIONS), bool),
                "actions": ((n,), np.int64), "active": ((n,), bool), "robot_reward": ((n,), np.float32),
                **critic_shapes(n)})
        return WalkerState(PatchExtractor(batch.core, RADIUS), buffer, ~batch.core.ended)

    def decide(self, batch: EpisodeBatch, state: WalkerState, choice: ActionChoice) -> Decision:
        core = batch.core
        obs, mask = local_view(core, state.patch), action_mask(core)
        actions = choice(masked_logits(self.actor(torch.from_numpy(obs)), torch.from_numpy(mask)))
        state.running = ~core.ended
        if state.buffer is not None:
            store_critic_inputs(state.buffer, core, self.env.horizon)
            state.buffer.add(obs=obs, mask=mask, actions=actions.numpy(), active=~core.done & state.running[:, None])
        return Decision(actions=actions, payload=0.0)

    def observe(self, batch: EpisodeBatch, state: WalkerState, result: StepResult) -> None:
        if state.buffer is not None:
            state.buffer.add(robot_reward=robot_rewards(result))  # each robot's own terms
            state.buffer.reward(result.reward, state.running)

    def update(self, state: WalkerState) -> dict[str, float]:
        p, buf = self.params, state.buffer
        if p.protocol != "mappo" or buf is None:
            raise ValueError("mappo_walker learns with protocol = 'mappo' only")
        gen = update_generator(self.seed, self.iterations)  # this update's minibatch shuffling
        crit = mappo_critic(self.critic, self.critic_opt, buf, p, gen=gen)  # GAE advantages (T, B, N)
        active = buf.tensor("active").reshape(-1)
        rows = torch.nonzero(active).squeeze(-1)  # the robot-steps that count
        obs = buf.tensor("obs").reshape(-1, self.n_obs)[rows]
        mask = buf.tensor("mask").reshape(-1, N_ACTIONS)[rows]
        actions = buf.tensor("actions").reshape(-1)[rows]

        def log_probs(ix: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
            logp_all = torch.log_softmax(masked_logits(self.actor(obs[ix]), mask[ix]), dim=-1)
            logp = logp_all.gather(-1, actions[ix, None])
            return logp, -(logp_all.exp() * logp_all).sum(-1, keepdim=True), torch.ones_like(logp)

        advantages = crit.robot_adv.reshape(-1)[rows][:, None]
        out = ppo_actor_update(PPOBatch(len(rows), log_probs, advantages), self.actor_opt, p.ppo_epochs,
                               p.ppo_minibatches, p.ppo_clip, p.entropy_coef, p.max_grad_norm, gen)
        return {**crit.losses, **out}
