"""The mappo training protocol (algorithms/common/ppo.py)."""
from __future__ import annotations

import pytest
import torch

from algorithms.common.ppo import RobotCritic, gae, robot_rewards
from algorithms.registry import method_class
from envs.config import EnvConfig


def test_gae__one_step_td_with_lambda_0_and_monte_carlo_with_lambda_1() -> None:
    r = torch.tensor([[[1.0]], [[2.0]], [[3.0]], [[9.0]]])  # (T=4, B=1, K=1)
    v = torch.tensor([[[0.5]], [[1.0]], [[1.5]], [[7.0]]])
    running = torch.tensor([[True], [True], [True], [False]])  # ended after t = 2
    adv0, _ = gae(r, v, running, gamma=0.9, lam=0.0)
    assert adv0[:, 0, 0].tolist() == pytest.approx([1 + 0.9 * 1.0 - 0.5, 2 + 0.9 * 1.5 - 1.0, 3 - 1.5, 0.0])
    adv1, ret1 = gae(r, v, running, gamma=1.0, lam=1.0)
    assert ret1[:, 0, 0].tolist() == pytest.approx([6.0, 5.0, 3.0, 0.0])  # Monte-Carlo, terminal at the end
    assert adv1[:, 0, 0].tolist() == pytest.approx([5.5, 4.0, 1.5, 0.0])


def test_robot_critic__per_robot_values_for_any_n() -> None:
    critic = RobotCritic(8)
    for n in (3, 7):
        out = critic(torch.rand(5, 2, n, 6), torch.rand(5, 2))
        assert out.shape == (5, 2, n)


def test_robot_rewards_average_to_the_team_reward() -> None:
    env = EnvConfig.make(n_robots=6, layout="tiny", horizon=10, loss_p=0.0, groups=2, on_goal="stay")
    m = method_class("decentralized")(env, {"batch_episodes": 2}, seed=0)
    batch = m.train_batch()
    res = batch.core.step(torch.zeros(2, 6, dtype=torch.int64).numpy() + 1)
    assert robot_rewards(res).mean(1) == pytest.approx(res.reward, abs=1e-6)


@pytest.mark.parametrize("method", ["decentralized", "ic3net", "hierarchical"])
@pytest.mark.parametrize("credit", ["robot", "team"])
def test_mappo_trains_and_is_recorded_in_the_params(method: str, credit: str) -> None:
    env = EnvConfig.make(n_robots=6, layout="tiny", horizon=12, loss_p=0.3, groups=2, on_goal="stay")
    m = method_class(method)(env, {"batch_episodes": 2, "protocol": "mappo", "credit": credit}, seed=1)
    before = [q.detach().clone() for q in m.modules()["critic"].parameters()]  # type: ignore[union-attr]
    rows = [r for _ in range(2) for r in m.train_iteration()]
    assert m.params.model_dump()["protocol"] == "mappo"
    assert all(r["clip_fraction"] >= 0.0 and r["diag_kl"] >= 0.0 for r in rows)
    after = list(m.modules()["critic"].parameters())  # type: ignore[union-attr]
    assert any(not torch.equal(a, b) for a, b in zip(before, after, strict=True))
    again = method_class(method)(env, {"batch_episodes": 2, "protocol": "mappo", "credit": credit}, seed=1)
    rows2 = [r for _ in range(2) for r in again.train_iteration()]
    assert [r["actor_loss"] for r in rows] == [r["actor_loss"] for r in rows2]  # deterministic


def test_the_default_protocol_is_the_papers() -> None:
    env = EnvConfig.make(n_robots=6, layout="tiny", horizon=12, loss_p=0.3, groups=2, on_goal="stay")
    m = method_class("decentralized")(env, {}, seed=1)
    assert m.params.protocol == "paper" and type(m.critic).__name__ == "CentralCritic"  # type: ignore[attr-defined]


def test_hierarchical_mappo_trains_both_levels() -> None:
    env = EnvConfig.make(n_robots=6, layout="tiny", horizon=12, loss_p=0.3, groups=2, on_goal="stay")
    m = method_class("hierarchical")(env, {"batch_episodes": 2, "protocol": "mappo"}, seed=1)
    ref = [q.detach().clone() for q in m.reference.parameters()]  # type: ignore[attr-defined]
    loc = [q.detach().clone() for q in m.local.parameters()]  # type: ignore[attr-defined]
    m.train_iteration()
    assert any(not torch.equal(a, b) for a, b in zip(ref, m.reference.parameters(), strict=True))  # type: ignore[attr-defined]
    assert any(not torch.equal(a, b) for a, b in zip(loc, m.local.parameters(), strict=True))  # type: ignore[attr-defined]
