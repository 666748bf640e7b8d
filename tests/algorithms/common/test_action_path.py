"""ActionPath: the action-aligned linear logit path, on hand numbers. Runtime < 1 s."""
from __future__ import annotations

import numpy as np
import torch

from algorithms.common.action_path import ACTION_GAIN, ActionPath, progress_index
from algorithms.common.episodes import EpisodeBatch, batch_rng
from algorithms.common.robot_obs import local_view
from envs.config import EnvConfig
from envs.observations import PatchExtractor, action_progress


def test_action_path__adds_nothing_at_init_and_gain_times_v_phi_after() -> None:
    path = ActionPath(np.array([[0, 1, 2, 3, 4], [5, 5, 6, 6, 7]]))
    obs = torch.arange(8.0)[None]  # phi(a) = (obs[a], obs[idx2[a]])
    logits = torch.tensor([[0.5, -1.0, 0.0, 2.0, 1.0]])
    assert torch.equal(path(obs, logits), logits)
    with torch.no_grad():
        path.weight.copy_(torch.tensor([1.0, -0.5]))
    expected = logits + ACTION_GAIN * torch.tensor([[0 - 2.5, 1 - 2.5, 2 - 3.0, 3 - 3.0, 4 - 3.5]])
    assert torch.allclose(path(obs, logits), expected)


def test_progress_index__points_at_action_progress_in_the_local_view() -> None:
    env = EnvConfig(n_robots=5, layout="tiny")
    core = EpisodeBatch(env, 2, batch_rng(0, 0, 0)).core
    feats = local_view(core, PatchExtractor(core, 2))
    assert np.array_equal(feats[..., progress_index()[0]], action_progress(core))
