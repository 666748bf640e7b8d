"""Reference and local policies: Proposition 1 (structure), any group size.

Runtime: under 1 s.
"""
from __future__ import annotations

import inspect

import numpy as np
import torch

from algorithms.common.episodes import EpisodeBatch, batch_rng
from algorithms.hierarchical.method import HierarchicalMethod
from algorithms.hierarchical.policies import LocalPolicy, ReferencePolicy
from envs.config import EnvConfig
from envs.observations import PatchExtractor, robot_features


def test_local_policy__signature_has_no_inter_group_input() -> None:
    params = list(inspect.signature(LocalPolicy.forward).parameters)
    assert params == ["self", "robots", "mask", "ref", "action_mask"]


def test_local_policy__proposition1_shat_reaches_only_the_reference() -> None:
    """With r fixed, changing S-hat (the neighbour patches) leaves pi's output unchanged,
    while mu's output does change."""
    env = EnvConfig.make(n_robots=12, layout="tiny", horizon=10, loss_p=0.2)
    m = HierarchicalMethod(env, {}, seed=0)
    batch = EpisodeBatch(env, 3, batch_rng(0, 0, 0), m.layout)
    own = robot_features(batch.core, PatchExtractor(batch.core, 2), m.gs.groups).astype(np.float16)
    ctl = ~batch.core.done
    amask = m.layout.move_valid[batch.core.pos]
    rng = np.random.default_rng(0)
    nbr_a = rng.integers(0, 3, size=(3, 12, m.d_nbr)).astype(np.uint8)
    nbr_b = rng.integers(0, 3, size=(3, 12, m.d_nbr)).astype(np.uint8)
    ref = torch.from_numpy(rng.integers(0, m.params.ref_size, size=(4, 3)))
    with torch.no_grad():
        _, mu_a, pi_a = m.policy_forward(own, nbr_a, ctl, amask, ref=ref)
        _, mu_b, pi_b = m.policy_forward(own, nbr_b, ctl, amask, ref=ref)
        _, _, pi_c = m.policy_forward(own, nbr_a, ctl, amask, ref=(ref + 1) % m.params.ref_size)
    assert torch.equal(pi_a, pi_b)
    assert not torch.allclose(mu_a, mu_b)
    assert not torch.allclose(pi_a, pi_c)  # the reference does condition pi


def test_policies__any_group_size_same_weights() -> None:
    torch.manual_seed(0)
    ref_pol = ReferencePolicy(4, 4, 10, 16, 5)
    loc = LocalPolicy(4, 4, 61, 16, 5, obs_radius=2)
    for n in (1, 3, 25):
        feats = torch.randn(4, 2, n, 61)
        mask = torch.ones(4, 2, n, dtype=torch.bool)
        mask[:, :, -1] = False  # a padded slot
        assert ref_pol(torch.randn(4, 2, n, 10), mask).shape == (4, 2, 5)
        logp = loc(feats, mask, torch.zeros(4, 2, dtype=torch.int64), torch.ones(4, 2, n, 5, dtype=torch.bool))
        assert logp.shape == (4, 2, n, 5)
        assert torch.allclose(logp.exp().sum(-1), torch.ones(4, 2, n))


def test_local_policy__padding_does_not_change_real_robots() -> None:
    torch.manual_seed(1)
    loc = LocalPolicy(2, 2, 61, 16, 3, obs_radius=2)
    feats = torch.randn(2, 1, 3, 61)
    ref = torch.tensor([[0], [2]])
    am = torch.ones(2, 1, 4, 5, dtype=torch.bool)
    small = loc(feats, torch.ones(2, 1, 3, dtype=torch.bool), ref, am[:, :, :3])
    padded = loc(torch.cat([feats, torch.randn(2, 1, 1, 61)], dim=2),
                 torch.tensor([True, True, True, False]).expand(2, 1, 4), ref, am)
    assert torch.allclose(small, padded[:, :, :3], atol=1e-6)
