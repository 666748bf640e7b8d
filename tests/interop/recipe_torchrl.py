"""TorchRL: MAPPO on warehouse_v0 through PettingZooWrapper (docs/interop.md;
tests/interop/test_torchrl.py runs exactly this file)."""
import torch
from tensordict.nn import TensorDictModule
from torchrl.collectors import Collector
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.envs.libs.pettingzoo import PettingZooWrapper
from torchrl.modules import MaskedCategorical, MultiAgentMLP, ProbabilisticActor
from torchrl.objectives import ClipPPOLoss, ValueEstimators

from envs.warehouse_v0 import parallel_env

G = "robot"  # TorchRL groups agents robot_0..robot_{N-1} under "robot"


def make_env(seed: int, **config) -> PettingZooWrapper:
    # on_goal="remove" (the default): finished robots leave `agents`, so use_mask=True, and
    # done_on_any=False so the episode ends when every robot is done, not the first one.
    return PettingZooWrapper(env=parallel_env(**config), use_mask=True, done_on_any=False,
                             categorical_actions=True, seed=seed)


def make_agents(env: PettingZooWrapper) -> tuple[ProbabilisticActor, TensorDictModule]:
    n = len(env.group_map[G])
    n_obs = env.observation_spec[G, "observation", "observation"].shape[-1]
    obs = (G, "observation", "observation")
    actor = ProbabilisticActor(
        TensorDictModule(MultiAgentMLP(n_obs, 5, n, centralised=False, share_params=True,
                                       depth=2, num_cells=64), [obs], [(G, "logits")]),
        in_keys={"logits": (G, "logits"), "mask": (G, "action_mask")},
        out_keys=[(G, "action")], distribution_class=MaskedCategorical,
        return_log_prob=True, log_prob_key=(G, "sample_log_prob"))
    critic = TensorDictModule(MultiAgentMLP(n_obs, 1, n, centralised=True, share_params=True,
                                            depth=2, num_cells=64), [obs], [(G, "state_value")])
    return actor, critic


def train(env: PettingZooWrapper, actor, critic, frames: int, batch: int = 1000,
          epochs: int = 4, lr: float = 3e-3) -> None:
    loss = ClipPPOLoss(actor, critic, clip_epsilon=0.2, entropy_coeff=0.01,
                       normalize_advantage=True)
    loss.set_keys(reward=(G, "reward"), action=(G, "action"), value=(G, "state_value"),
                  sample_log_prob=(G, "sample_log_prob"), done=(G, "done"),
                  terminated=(G, "terminated"), advantage=(G, "advantage"),
                  value_target=(G, "value_target"))
    loss.make_value_estimator(ValueEstimators.GAE, gamma=0.98, lmbda=0.95)
    optim = torch.optim.Adam(loss.parameters(), lr)
    for data in Collector(env, actor, frames_per_batch=batch, total_frames=frames):
        with torch.no_grad():
            loss.value_estimator(data, params=loss.critic_network_params,
                                 target_params=loss.target_critic_network_params)
        alive = data[G, "mask"].unsqueeze(-1)  # robots that had left do not count
        data[G, "advantage"] = data[G, "advantage"] * alive
        data[G, "value_target"] = torch.where(alive, data[G, "value_target"],
                                              data[G, "state_value"])
        for _ in range(epochs):
            out = loss(data)
            total = out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]
            optim.zero_grad()
            total.backward()
            optim.step()


def arrived(env: PettingZooWrapper, actor, episodes: int) -> float:
    """Fraction of robots that reach their goal, with sampled actions (the greedy policy
    of a shared-parameter network deadlocks robots facing each other)."""
    hits = []
    with set_exploration_type(ExplorationType.RANDOM), torch.no_grad():
        for _ in range(episodes):
            td = env.rollout(10_000, actor)
            hits.append(td["next", G, "terminated"].any(0).float().mean())
    return float(torch.stack(hits).mean())
