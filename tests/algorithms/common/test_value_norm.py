"""ValueNorm: debiased running statistics of value targets, hand-checked. Runtime < 1 s."""
from __future__ import annotations

import torch

from algorithms.common.value_norm import ValueNorm


def test_value_norm__is_identity_before_any_update() -> None:
    norm = ValueNorm()
    x = torch.tensor([3.0, -2.0])
    assert torch.equal(norm.normalize(x), x) and torch.equal(norm.denormalize(x), x)


def test_value_norm__first_batch_gives_its_masked_mean_and_std() -> None:
    norm = ValueNorm(beta=0.9)
    targets = torch.tensor([[2.0, 4.0], [6.0, 100.0]])
    mask = torch.tensor([[True, True], [True, False]])  # 100 is masked out
    norm.update(targets, mask)
    mu, sigma = norm.stats()  # debiased: exactly the batch's mean 4 and std sqrt(8/3)
    assert torch.isclose(mu, torch.tensor(4.0))
    assert torch.isclose(sigma, torch.tensor((8.0 / 3.0) ** 0.5))
    y = norm.normalize(targets)
    assert torch.allclose(norm.denormalize(y), targets)


def test_value_norm__weights_recent_batches_by_beta() -> None:
    norm = ValueNorm(beta=0.5)
    ones = torch.ones(4, dtype=torch.bool)
    norm.update(torch.full((4,), 0.0), ones)
    norm.update(torch.full((4,), 3.0), ones)
    # mean = (0.5 * 0.5 * 0 + 0.5 * 3) / (1 - 0.25) = 2
    assert torch.isclose(norm.stats()[0], torch.tensor(2.0))


def test_value_norm__statistics_are_checkpointed_buffers() -> None:
    a, b = ValueNorm(), ValueNorm()
    a.update(torch.tensor([1.0, 5.0]), torch.ones(2, dtype=torch.bool))
    b.load_state_dict(a.state_dict())
    assert all(torch.equal(x, y) for x, y in zip(a.stats(), b.stats(), strict=True))
    assert {"mean", "mean_sq", "weight"} <= set(a.state_dict())
