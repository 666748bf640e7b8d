"""The shared trainer pieces: Monte-Carlo returns, team advantage losses, critic, buffer."""
from __future__ import annotations

import numpy as np
import torch

from algorithms.common.trainer import (
    CentralCritic,
    RolloutBuffer,
    mc_returns,
    policy_gradient_losses,
)


def test_mc_returns__is_undiscounted_reverse_cumsum():
    # eq:training_return: G_t = sum_{k=t}^{T-1} R_k, worked by hand.
    r = np.array([[1.0, 0.0], [2.0, -1.0], [3.0, 5.0]], dtype=np.float32)
    g = mc_returns(r)
    assert torch.equal(g, torch.tensor([[6.0, 4.0], [5.0, 4.0], [3.0, 5.0]]))


def test_policy_gradient_losses__hand_example_without_normalization():
    # One episode, two steps: G = [3, 1], V = [1, 1] -> A = [2, 0].
    rewards = np.array([[2.0], [1.0]], dtype=np.float32)
    running = np.ones((2, 1), dtype=bool)
    logp = torch.tensor([[-0.5], [-2.0]], requires_grad=True)
    values = torch.tensor([[1.0], [1.0]], requires_grad=True)
    out = policy_gradient_losses(logp, values, rewards, running, normalize=False)
    # actor = -(2 * -0.5 + 0 * -2) / 2 = 0.5 ; critic = ((1-3)^2 + (1-1)^2) / 2 = 2
    assert out.actor.item() == 0.5
    assert out.critic.item() == 2.0
    out.actor.backward()
    # the advantage is detached: the actor loss never trains the critic
    assert values.grad is None or torch.all(values.grad == 0)
    assert torch.allclose(logp.grad, torch.tensor([[-1.0], [0.0]]))


def test_policy_gradient_losses__ignores_steps_after_episode_end():
    rewards = np.array([[1.0], [0.0]], dtype=np.float32)
    logp = torch.tensor([[-1.0], [-100.0]])
    values = torch.zeros(2, 1)
    a = policy_gradient_losses(logp, values, rewards, np.array([[True], [False]]), normalize=False)
    b = policy_gradient_losses(logp * torch.tensor([[1.0], [0.0]]), values, rewards,
                               np.array([[True], [False]]), normalize=False)
    assert a.actor.item() == b.actor.item() == 1.0


def test_central_critic__accepts_any_team_size():
    critic = CentralCritic(hidden=16)
    for n in (3, 40, 100):
        v = critic(torch.rand(2, 5, n, 6), torch.rand(2, 5))
        assert v.shape == (2, 5)


def test_rollout_buffer__preallocates_and_returns_used_steps():
    buf = RolloutBuffer(10, 3, {"obs": ((4,), np.float32)})
    for t in range(4):
        buf.add(obs=np.full((3, 4), t, np.float32))
        buf.reward(np.ones(3), np.ones(3, bool))
    assert buf.tensor("obs").shape == (4, 3, 4)
    assert buf.tensor("obs")[3, 0, 0].item() == 3.0
    assert buf.rewards[:4].sum() == 12
