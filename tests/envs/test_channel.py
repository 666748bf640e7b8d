"""The lossy inter-group channel: loss statistics, graph masks, payload and groups."""
from __future__ import annotations

import numpy as np
import pytest

from envs.channel import GroupChannel, LossProcess, comm_graph, group_assignment, group_members
from envs.config import EnvConfig, loss_error
from envs.errors import BenchError


def loss_runs(lost: np.ndarray) -> np.ndarray:
    """Lengths of consecutive-loss runs along axis 0 of a (T, L) bool array."""
    padded = np.zeros((lost.shape[0] + 2, lost.shape[1]), dtype=np.int8)
    padded[1:-1] = lost
    edges = np.diff(padded, axis=0)  # +1 where a run starts, -1 after it ends
    starts = np.argwhere(edges.T == 1)
    ends = np.argwhere(edges.T == -1)
    return ends[:, 1] - starts[:, 1]  # both sorted by (link, time)


def sample(model: str, p: float, steps: int = 4000, seed: int = 0, burst: float = 4.0) -> np.ndarray:
    """(steps, links) bool: True where the message was lost."""
    proc = LossProcess((8, 4, 4), p, np.random.default_rng(seed), model, burst_length=burst)
    return np.stack([~proc.step() for _ in range(steps)]).reshape(steps, -1)


def test_bernoulli_loss_rate_matches_p() -> None:
    lost = sample("bernoulli", 0.3)  # 512k link-steps: standard error 0.0007
    assert abs(lost.mean() - 0.3) < 0.005


def test_bernoulli_losses_are_independent_over_time() -> None:
    lost = sample("bernoulli", 0.3)
    # P(lost at t+1 | lost at t) = p for i.i.d. losses.
    cond = lost[1:][lost[:-1]].mean()
    assert abs(cond - 0.3) < 0.01
    assert abs(loss_runs(lost).mean() - 1 / 0.7) < 0.03  # geometric runs, mean 1/(1-p)


def test_gilbert_elliott_has_the_same_mean_loss_and_bursts_of_the_given_length() -> None:
    lost = sample("gilbert_elliott", 0.3, steps=8000, burst=4.0)
    assert abs(lost.mean() - 0.3) < 0.015  # correlated samples: looser than Bernoulli
    runs = loss_runs(lost)
    assert abs(runs.mean() - 4.0) < 0.2
    bern = loss_runs(sample("bernoulli", 0.3))
    assert runs.mean() > 2.5 * bern.mean()


@pytest.mark.parametrize(("p", "burst"), [(0.8, 4.0), (0.9, 16.0)])
def test_gilbert_elliott_keeps_a_high_mean_loss_up_to_what_its_bursts_allow(p: float, burst: float) -> None:
    lost = sample("gilbert_elliott", p, steps=8000, burst=burst)  # p = L / (L + 1): P(G -> B) = 1
    assert abs(lost.mean() - p) < 0.02
    assert abs(loss_runs(lost).mean() - burst) < 0.1 * burst


@pytest.mark.parametrize(("p", "burst", "limit"), [(0.9, 4.0, "0.8"), (0.6, 1.0, "0.5"), (0.81, 4.0, "0.8")])
def test_gilbert_elliott_refuses_a_loss_its_bursts_cannot_have(p: float, burst: float, limit: str) -> None:
    # The chain would need P(Good -> Bad) > 1; quietly capping it gave a mean loss of
    # L / (L + 1) instead of p (0.8 for p = 0.9, L = 4). The environment refuses it where
    # the value enters (the loss rule, envs.config.loss_error); LossProcess takes its values.
    found = loss_error(p, "gilbert_elliott", burst)
    assert found is not None and found[0] == ("loss_p", "burst_length") and f"at most {limit}" in found[1]
    with pytest.raises(BenchError, match=f"loss_p={p:g} with burst_length={burst:g}: .*at most {limit}"):
        EnvConfig.make(loss_p=p, loss_model="gilbert_elliott", burst_length=burst)
    EnvConfig.make(loss_p=p, loss_model="bernoulli", burst_length=burst)  # Bernoulli has no bursts


def test_extreme_loss_probabilities_deliver_always_or_never() -> None:
    for model in ("bernoulli", "gilbert_elliott"):
        assert not sample(model, 0.0, steps=50).any()
        assert sample(model, 1.0, steps=50).all()


def test_unknown_loss_model_is_rejected() -> None:
    with pytest.raises(ValueError, match="unknown loss model 'pareto'"):
        LossProcess((2, 2), 0.1, np.random.default_rng(0), "pareto")


@pytest.mark.parametrize("model", ["bernoulli", "gilbert_elliott"])
def test_diagonal_and_non_edges_are_never_available(model: str) -> None:
    cfg = EnvConfig.make(n_robots=10, groups=5, comm_graph="ring", loss_p=0.0, loss_model=model)
    chan = GroupChannel(cfg, batch=3, rng=np.random.default_rng(0))
    ring = np.zeros((5, 5), dtype=bool)
    for z in range(5):
        ring[(z - 1) % 5, z] = ring[(z + 1) % 5, z] = True
    np.testing.assert_array_equal(chan.adjacency, ring)
    for _ in range(20):  # no loss: availability is exactly the graph
        np.testing.assert_array_equal(chan.step(), np.broadcast_to(ring, (3, 5, 5)))
    lossy = GroupChannel(cfg.model_copy(update={"loss_p": 0.5}), 3, np.random.default_rng(1))
    avail = np.stack([lossy.step() for _ in range(200)])  # (T, B, Z, Z)
    assert not avail[..., ~ring].any()
    assert 0.4 < avail[..., ring].mean() < 0.6


def test_complete_graph_links_every_pair_of_distinct_groups() -> None:
    adj = comm_graph(4)
    assert adj.sum() == 12
    assert not adj.diagonal().any()
    with pytest.raises(ValueError, match="unknown comm_graph 'star'"):
        comm_graph(4, "star")


@pytest.mark.parametrize(("n", "z", "d_m"), [(10, 4, 3), (20, 4, 3), (7, 3, 5), (100, 10, 3)])
def test_payload_counts_on_the_complete_graph(n: int, z: int, d_m: int) -> None:
    cfg = EnvConfig.make(n_robots=n, groups=z, d_m=d_m)
    chan = GroupChannel(cfg, batch=1, rng=np.random.default_rng(0))
    assert chan.payload_hier == (z - 1) * n * d_m
    assert chan.payload_dec == n * (n - 1) * d_m


def test_payload_on_a_ring_counts_two_outgoing_links_per_group() -> None:
    cfg = EnvConfig.make(n_robots=10, groups=5, comm_graph="ring")
    chan = GroupChannel(cfg, batch=1, rng=np.random.default_rng(0))
    assert chan.payload_hier == 2 * 10 * 3


def test_robot_i_belongs_to_group_i_mod_z() -> None:
    assert group_assignment(7, 3).tolist() == [0, 1, 2, 0, 1, 2, 0]
    assert group_members(7, 3).tolist() == [[0, 3, 6], [1, 4, -1], [2, 5, -1]]


@pytest.mark.parametrize(("n", "z"), [(20, 4), (21, 4), (23, 4), (100, 7), (5, 5), (9, 1)])
def test_group_sizes_differ_by_at_most_one(n: int, z: int) -> None:
    sizes = np.bincount(group_assignment(n, z), minlength=z)
    assert sizes.sum() == n
    assert sizes.max() - sizes.min() <= 1


@pytest.mark.parametrize("model", ["bernoulli", "gilbert_elliott"])
def test_same_seed_reproduces_the_availability_sequence(model: str) -> None:
    cfg = EnvConfig.make(n_robots=12, groups=4, loss_p=0.3, loss_model=model)

    def run(seed: int) -> np.ndarray:
        chan = GroupChannel(cfg, batch=4, rng=np.random.default_rng(seed))
        return np.stack([chan.step() for _ in range(50)])

    np.testing.assert_array_equal(run(7), run(7))
    assert (run(7) != run(8)).any()
