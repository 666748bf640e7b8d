"""The shared trainer pieces: returns, team advantage, critic inputs and update, buffer.

Hand-worked numbers throughout; runtime about 3 s (the per-method critic test trains one
tiny update of each learned method).
"""
from __future__ import annotations

import numpy as np
import pytest
import torch

from algorithms.common.trainer import (
    CentralCritic,
    RolloutBuffer,
    clip_and_step,
    critic_features,
    critic_inputs,
    critic_loss,
    critic_shapes,
    critic_update,
    mc_returns,
    policy_gradient_losses,
    store_critic_inputs,
    team_advantage,
)
from algorithms.registry import method_class
from envs.config import EnvConfig
from envs.core import WarehouseCore
from envs.layouts import from_ascii
from envs.scenarios import validate_scenario


def test_mc_returns__is_undiscounted_reverse_cumsum():
    # eq:training_return: G_t = sum_{k=t}^{T-1} R_k, worked by hand.
    r = np.array([[1.0, 0.0], [2.0, -1.0], [3.0, 5.0]], dtype=np.float32)
    g = mc_returns(r)
    assert torch.equal(g, torch.tensor([[6.0, 4.0], [5.0, 4.0], [3.0, 5.0]]))
    assert mc_returns(r.astype(np.float64)).dtype == torch.float32


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
    assert out.advantage_mean == 1.0 and out.return_mean == 2.0
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
    # The reported means count running steps only: A = G = [1, 0], one running step.
    assert a.advantage_mean == 1.0 and a.return_mean == 1.0


def test_team_advantage__normalized_by_the_rms_of_running_steps():
    # Episode 0 runs 2 steps, episode 1 only its first: G = [[3, 4], [1, 100]], V = 1 ->
    # A = [[2, 3], [0, 99]]; running entries 2, 3, 0: RMS = sqrt(13 / 3); the ended
    # step's 99 neither enters the RMS nor the mask.
    rewards = np.array([[2.0, -96.0], [1.0, 100.0]], dtype=np.float32)
    running = np.array([[True, True], [True, False]])
    adv, g, mask, n = team_advantage(torch.ones(2, 2), rewards, running, normalize=True)
    rms = np.sqrt(13.0 / 3.0)
    assert np.allclose(adv[:, 0].numpy(), np.array([2.0, 0.0]) / rms)
    assert float(adv[0, 1]) == pytest.approx(3.0 / rms)
    assert torch.equal(g, torch.tensor([[3.0, 4.0], [1.0, 100.0]]))
    assert torch.equal(mask, torch.tensor([[1.0, 1.0], [1.0, 0.0]])) and n.item() == 3.0
    assert mask.dtype == torch.float32
    default, *_ = team_advantage(torch.ones(2, 2), rewards, running)  # normalize by default
    assert torch.equal(default, adv)
    # Small advantages (RMS < 1) are scaled up to unit RMS too.
    small, *_ = team_advantage(torch.zeros(2, 1), np.array([[0.1], [0.2]], np.float32),
                               np.ones((2, 1), bool))
    assert np.allclose(small[:, 0].numpy(), np.array([0.3, 0.2]) / np.sqrt(0.065))
    raw, *_ = team_advantage(torch.ones(2, 2), rewards, running, normalize=False)
    assert torch.equal(raw, torch.tensor([[2.0, 3.0], [0.0, 99.0]]))
    # All advantages zero: no division by zero.
    zero, *_ = team_advantage(torch.tensor([[3.0, 4.0], [1.0, 100.0]]), rewards, running)
    assert torch.equal(zero, torch.zeros(2, 2))


def test_team_advantage__is_detached_from_the_critic():
    values = torch.zeros(2, 1, requires_grad=True)
    adv, *_ = team_advantage(values, np.ones((2, 1), np.float32), np.ones((2, 1), bool))
    assert not adv.requires_grad


def test_critic_loss__masks_ended_steps_and_divides_by_running_steps():
    values = torch.tensor([[1.0, 2.0], [0.0, 50.0]])
    returns = torch.tensor([[3.0, 2.0], [1.0, 0.0]])
    mask = torch.tensor([[1.0, 1.0], [1.0, 0.0]])
    # (1-3)^2 + 0 + (0-1)^2 over 3 running steps; the masked 2500 does not count.
    assert critic_loss(values, returns, mask, torch.tensor(3.0)).item() == pytest.approx(5.0 / 3.0)


def test_clip_and_step__clips_the_global_norm_then_steps():
    w = torch.nn.Parameter(torch.tensor([0.0, 0.0]))
    opt = torch.optim.SGD([w], lr=1.0)
    w.grad = torch.tensor([3.0, 4.0])  # norm 5
    assert clip_and_step(opt, 1.0) == pytest.approx(5.0)
    assert torch.allclose(w.detach(), torch.tensor([-0.6, -0.8]))  # unit-norm step
    w.grad = torch.tensor([0.3, 0.4])  # below the clip: unchanged
    assert clip_and_step(opt, 1.0) == pytest.approx(0.5)
    assert torch.allclose(w.detach(), torch.tensor([-0.9, -1.2]))


def small_core() -> WarehouseCore:
    layout = from_ascii("....\n.@..\n....")
    core = WarehouseCore(EnvConfig.make(n_robots=2, groups=1, loss_p=0.0, horizon=8), layout)
    s, g = validate_scenario(layout, 2, [(0, 0), (2, 3)], [(2, 0), (2, 2)])
    core.reset(s[None], g[None])
    return core


def test_critic_features__hand_example():
    core = small_core()  # 3 x 4 grid: H + W = 7
    f = critic_features(core)
    assert f.shape == (1, 2, 6) and f.dtype == np.float32
    assert np.allclose(f[0, 0], [0 / 3, 0 / 4, 2 / 3, 0 / 4, 2 / 7, 0])
    assert np.allclose(f[0, 1], [2 / 3, 3 / 4, 2 / 3, 2 / 4, 1 / 7, 0])
    core.step(np.array([[4, 2]]))  # robot 1 moves left onto its goal and completes
    f = critic_features(core)
    assert np.allclose(f[0, 1], [2 / 3, 2 / 4, 2 / 3, 2 / 4, 0, 1])
    inputs = critic_inputs(core, horizon=8)
    assert np.array_equal(inputs["critic"], f)
    assert inputs["t_frac"].tolist() == [1 / 8] and inputs["t_frac"].dtype == np.float32
    buf = RolloutBuffer(8, 1, critic_shapes(2))
    buf.add(**inputs)
    assert buf.data["critic"].shape == (8, 1, 2, 6) and buf.data["t_frac"].shape == (8, 1)
    # The in-place writer used by the rollouts stores the same X_t and t / T in the current row.
    buf.reward(np.zeros(1, np.float32), np.ones(1, bool))
    store_critic_inputs(buf, core, horizon=8)
    assert np.array_equal(buf.data["critic"][1], f) and buf.data["t_frac"][1].tolist() == [1 / 8]


def test_central_critic__reads_time_and_the_done_fraction():
    # Weights set by hand so that V = t/T + 10 * (fraction of robots done).
    critic = CentralCritic(hidden=4)
    with torch.no_grad():
        for p in critic.parameters():
            p.zero_()
        critic.rho[0].weight[0, 4] = 1.0  # t_frac
        critic.rho[0].weight[1, 5] = 1.0  # done fraction
        critic.rho[2].weight[0, :2] = torch.tensor([1.0, 10.0])
    robots = torch.zeros(2, 4, 6)
    robots[0, :3, 5] = 1.0  # 3 of 4 robots done in state 0
    robots[1, :, 4] = 5.0  # distance column is not "done"
    v = critic(robots, torch.tensor([0.25, 0.5]))
    assert torch.allclose(v, torch.tensor([0.25 + 7.5, 0.5]))


def test_central_critic__phi_is_a_two_layer_relu_net_mean_pooled_over_robots():
    # Hand weights: phi(x) = [|x_0|, 0, 0, 0] (ReLU, mix, ReLU), V = mean over robots of |x_0|.
    critic = CentralCritic(hidden=4)
    with torch.no_grad():
        for p in critic.parameters():
            p.zero_()
        critic.phi[0].weight[0, 0], critic.phi[0].weight[1, 0] = -1.0, 1.0  # relu(-x0), relu(x0)
        critic.phi[2].weight[0, :2] = 1.0  # |x0|
        critic.phi[2].weight[1, :2] = -1.0  # relu(-|x0|) = 0
        critic.rho[0].weight[0, 0], critic.rho[0].weight[0, 1] = 1.0, -1.0
        critic.rho[2].weight[0, 0] = 1.0
    robots = torch.zeros(1, 2, 6)
    robots[0, :, 0] = torch.tensor([0.5, -0.25])
    assert torch.allclose(critic(robots, torch.zeros(1)), torch.tensor([0.375]))


def test_central_critic__accepts_any_team_size_and_ignores_robot_order():
    critic = CentralCritic(hidden=16)
    for n in (3, 40, 100):
        x = torch.rand(2, 5, n, 6)
        v = critic(x, torch.rand(2, 5))
        assert v.shape == (2, 5)
    perm = torch.randperm(100)
    t = torch.rand(2, 5)
    assert torch.allclose(critic(x, t), critic(x[..., perm, :], t), atol=1e-6)


def test_critic_update__advantage_before_one_clipped_adam_step():
    torch.manual_seed(0)
    critic = CentralCritic(hidden=8)
    twin = CentralCritic(hidden=8)
    twin.load_state_dict(critic.state_dict())
    buf = RolloutBuffer(3, 2, critic_shapes(4))
    gen = np.random.default_rng(0)
    for t in range(3):
        buf.add(critic=gen.random((2, 4, 6), dtype=np.float32), t_frac=np.full(2, t / 3, np.float32))
        buf.reward(gen.normal(size=2).astype(np.float32), np.array([True, t < 2]))
    opt = torch.optim.Adam(critic.parameters(), lr=0.1)
    frozen = CentralCritic(hidden=8)
    frozen.load_state_dict(critic.state_dict())
    raw = critic_update(frozen, torch.optim.SGD(frozen.parameters(), lr=0.0), buf,
                        normalize=False, max_grad_norm=1.0)
    step = critic_update(critic, opt, buf, normalize=True, max_grad_norm=1e-3)
    # Reference: values before the step, the masked squared error, clip, one Adam step.
    values = twin(buf.tensor("critic"), buf.tensor("t_frac"))
    adv, g, mask, n = team_advantage(values, buf.rewards[:3], buf.running[:3], True)
    assert torch.equal(step.adv, adv) and torch.equal(step.returns, g) and torch.equal(step.mask, mask)
    assert torch.equal(step.values, values.detach()) and not step.values.requires_grad  # before the step
    unnormalized, *_ = team_advantage(values, buf.rewards[:3], buf.running[:3], False)
    assert torch.equal(raw.adv, unnormalized) and not torch.allclose(raw.adv, adv)
    assert step.n.item() == 5.0
    loss = (((values - g) ** 2) * mask).sum() / n
    assert step.loss == pytest.approx(float(loss.detach()))
    ref_opt = torch.optim.Adam(twin.parameters(), lr=0.1)
    loss.backward()
    torch.nn.utils.clip_grad_norm_(twin.parameters(), 1e-3)
    ref_opt.step()
    for a, b in zip(critic.parameters(), twin.parameters(), strict=True):
        assert torch.allclose(a, b, atol=1e-7)
    assert not all(torch.equal(a, b) for a, b in zip(critic.parameters(), CentralCritic(8).parameters(), strict=True))


@pytest.mark.parametrize("name", ["decentralized", "ic3net", "hierarchical"])
def test_every_learned_method__steps_its_central_critic(name: str):
    env = EnvConfig(n_robots=4, layout="tiny", horizon=10, groups=2, loss_p=0.2)
    m = method_class(name)(env, {"batch_episodes": 2}, seed=0)
    before = [p.detach().clone() for p in m.critic.parameters()]
    rows = m.train_iteration()
    assert all(np.isfinite(r["critic_loss"]) and r["critic_loss"] > 0 for r in rows)
    after = list(m.critic.parameters())
    assert all(not torch.equal(a, b) for a, b in zip(before, after, strict=True))
    assert m.params.max_grad_norm == 10.0  # one clip for every method (LearnedParams)


def test_rollout_buffer__preallocates_and_returns_used_steps():
    buf = RolloutBuffer(10, 3, {"obs": ((4,), np.float32)})
    for t in range(4):
        buf.add(obs=np.full((3, 4), t, np.float32))
        buf.reward(np.full(3, t, np.float32), np.array([True, t < 2, False]))
    assert buf.t == 4 and buf.rewards.dtype == np.float32
    assert buf.tensor("obs").shape == (4, 3, 4)
    assert buf.tensor("obs")[3, 0, 0].item() == 3.0
    assert buf.rewards[:4, 0].tolist() == [0, 1, 2, 3] and buf.rewards[4:].sum() == 0
    assert buf.running[:4, 1].tolist() == [True, True, False, False] and not buf.running[:, 2].any()
