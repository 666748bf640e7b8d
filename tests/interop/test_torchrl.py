"""TorchRL's PettingZooWrapper on warehouse_v0, out of the box, and the MAPPO recipe of
docs/interop.md (tests/interop/recipe_torchrl.py) learning on the tiny layout."""
from __future__ import annotations

import pytest
import torch

pytest.importorskip("torchrl")
from torchrl.envs.libs.pettingzoo import PettingZooWrapper  # noqa: E402

from envs.warehouse_v0 import parallel_env  # noqa: E402
from tests.interop.recipe_torchrl import G, arrived, make_agents, make_env, train  # noqa: E402

TINY = dict(n_robots=4, layout="tiny", horizon=40)


def test_torchrl__wrapper_rolls_out_the_raw_env():
    # A user's reproduction, as written: the mask was in infos too and TorchRL crashed.
    env = PettingZooWrapper(env=parallel_env(n_robots=8, layout="tiny"), use_mask=True)
    td = env.rollout(5)
    assert td[G, "action_mask"].shape == (len(td), 8, 5)
    assert "action_mask" not in td[G, "info"].keys()


def test_torchrl__robot_starting_on_its_goal_keeps_the_agent_set():
    env = PettingZooWrapper(env=parallel_env(n_robots=2, layout="tiny", horizon=10),
                            use_mask=True, done_on_any=False)
    td = env.reset(options={"starts": [(1, 1), (1, 2)], "goals": [(1, 1), (7, 11)]})
    assert td[G, "mask"].tolist() == [True, True]
    assert td[G, "action_mask"][0].tolist() == [False, False, False, False, True]
    td = env.rollout(3, auto_reset=False, tensordict=td)
    assert td["next", G, "terminated"][0].squeeze(-1).tolist() == [True, False]
    assert td["next", G, "mask"][0].tolist() == [False, True]
    assert not td["next", "done"][:2].any()  # done_on_any=False: one robot does not end it


def test_torchrl__done_on_any_default_ends_at_the_first_arrival():
    # Why the recipe passes done_on_any=False in remove mode.
    env = PettingZooWrapper(env=parallel_env(n_robots=2, layout="tiny", horizon=10),
                            use_mask=True)
    td = env.reset(options={"starts": [(1, 1), (1, 2)], "goals": [(1, 1), (7, 11)]})
    td = env.rollout(3, auto_reset=False, tensordict=td)
    assert len(td) == 1 and td["next", "done"].all()


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0])
def test_torchrl__mappo_recipe_learns_on_tiny(seed):
    # Budget 3,000 env steps (12,000 agent-steps), about a minute on one loaded core.
    # Measured (fraction of robots arriving, 20 sampled episodes): see docs/decisions/0019.
    torch.manual_seed(seed)
    env = make_env(seed, **TINY)
    actor, critic = make_agents(env)
    before = arrived(env, actor, episodes=20)
    train(env, actor, critic, frames=3000)
    after = arrived(env, actor, episodes=20)
    assert after > before + 0.25, (before, after)
