"""Equal footing between the learned methods: what one gets by default, every one gets.

The action-aligned logit path (``ActionPath``; docs/decisions/0136,
0137) lets a policy learn "make progress, avoid the robot on the
target cell" early; on the validation configurations a method without it did not learn
(IC3Net: 2% training success without, 21-79% with). A method that silently lost it would
be compared on a missing inductive bias, not on coordination."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from algorithms.common.action_path import ACTION_GAIN, ActionPath, progress_index
from algorithms.common.robot_obs import robots_on_target_index
from algorithms.registry import method_class
from envs.config import EnvConfig

ENV = EnvConfig(n_robots=6, layout="tiny", horizon=15, groups=2, loss_p=0.2)
RADIUS = 2  # every learned method's default view radius


def _path_rows(method: str) -> np.ndarray:
    """The (K, 5) observation columns of ``method``'s default action-aligned path."""
    m = method_class(method)(ENV, {}, seed=0)
    if method == "hierarchical":
        assert m.params.obs_radius == RADIUS
        return m.local.action_idx.numpy()
    path = m.actor.path if method == "decentralized" else m.policy.path
    assert isinstance(path, ActionPath), f"{method} has no action path by default"
    assert m.params.patch_radius == RADIUS
    return path.index.numpy()


@pytest.mark.parametrize("method", ["hierarchical", "decentralized", "ic3net"])
def test_every_learned_method_has_the_progress_and_robot_on_target_path_by_default(method: str) -> None:
    rows = _path_rows(method)
    want = np.concatenate([progress_index(), robots_on_target_index(RADIUS)])
    assert np.array_equal(rows[:2], want)  # the baselines may add columns of their own inputs


def test_the_path_starts_at_zero_with_one_gain() -> None:
    m = method_class("ic3net")(ENV, {}, seed=0)
    assert torch.count_nonzero(m.policy.path.weight) == 0
    h = method_class("hierarchical")(ENV, {}, seed=0)
    assert torch.count_nonzero(h.local.action_w) == 0 and ACTION_GAIN == 10.0


def test_ic3net_reference_head_stays_available() -> None:
    m = method_class("ic3net")(ENV, {"action_path": False}, seed=0)
    assert m.policy.path is None
