"""Message delay (envs.channel.DelayLine, Channel with delay > 0): a message sent at t
arrives at exactly t + d, and never when it is lost."""
from __future__ import annotations

import numpy as np
import pytest

from envs.channel import Channel, DelayLine
from envs.config import EnvConfig
from envs.errors import BenchError


def _oracle(delivered: np.ndarray, delays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per step, per link: did a fresher message arrive, and the send step held after it,
    from the plain definition (sends at t arrive at t + d unless lost; keep the newest)."""
    steps = delivered.shape[0]
    arrived = np.zeros_like(delivered)
    held = np.full(delivered.shape, -1)
    for link in np.ndindex(delivered.shape[1:]):
        best = -1
        for u in range(steps):
            due = [t for t in range(u + 1) if delivered[(t, *link)] and t + delays[(t, *link)] == u]
            if due and max(due) > best:
                best = max(due)
                arrived[(u, *link)] = True
            held[(u, *link)] = best
    return arrived, held


@pytest.mark.parametrize("model", ["fixed", "geometric"])
def test_delay_line__sent_at_t_arrives_at_t_plus_d_never_when_lost(model):
    rng = np.random.default_rng(4)
    steps, shape, bound = 30, (2, 3, 3), 5
    delivered = rng.random((steps, *shape)) > 0.3
    line = DelayLine(shape, 2.0, model, bound, np.random.default_rng(9))
    twin = DelayLine(shape, 2.0, model, bound, np.random.default_rng(9))
    delays = np.stack([twin.delays() for _ in range(steps)])  # the same draws, in order
    if model == "fixed":
        assert (delays == 2).all()
    else:
        assert delays.min() == 0 and delays.max() == bound  # spread, cut to the bound
    got_arrived, got_held = [], []
    for t in range(steps):
        got_arrived.append(line.step(delivered[t]))
        got_held.append(line.sent_at.copy())
    want_arrived, want_held = _oracle(delivered, delays)
    assert np.array_equal(np.stack(got_arrived), want_arrived)
    assert np.array_equal(np.stack(got_held), want_held)


def test_delay_line__fixed_delay_exactly():
    line = DelayLine((1,), 3, "fixed", 3, None)
    sends = [True, False, True, True, False, False, False, False]
    arrivals = [bool(line.step(np.array([ok]))[0]) for ok in sends]
    assert arrivals == [False, False, False, True, False, True, True, False]  # t + 3, lost t = 1 never


def test_channel__delayed_messages_are_not_available_when_sent():
    cfg = EnvConfig.make(n_robots=8, layout="tiny", groups=4, loss_p=0.0, delay=2)
    chan = Channel(cfg, 2, np.random.default_rng(0))
    for t in range(6):
        now = chan.step()
        assert not now.any()  # nothing arrives the step it is sent
        assert np.array_equal(chan.arrived, np.broadcast_to(chan.adjacency, now.shape) if t >= 2 else now)
        assert chan.sent_at is not None
        assert (chan.sent_at[:, chan.adjacency] == t - 2).all() if t >= 2 else (chan.sent_at == -1).all()


def test_channel__delay_keeps_the_loss_pattern_of_delay_zero():
    cfg = EnvConfig.make(n_robots=8, layout="tiny", groups=4, loss_p=0.4, loss_model="gilbert_elliott")
    plain = Channel(cfg, 3, np.random.default_rng(5), "robots")
    late = Channel(cfg.model_copy(update={"delay": 3.0}), 3, np.random.default_rng(5), "robots")
    sent = [plain.step() for _ in range(12)]
    got = [late.step() | late.arrived for _ in range(12)]
    for t in range(3, 12):
        assert np.array_equal(got[t], sent[t - 3])
    assert plain.sent_at is None


def test_config__delay_errors_are_one_clear_line():
    with pytest.raises(BenchError, match="whole number of steps"):
        EnvConfig.make(delay=1.5)
    with pytest.raises(BenchError, match="exceeds delay_max"):
        EnvConfig.make(delay=20)
    with pytest.raises(BenchError, match="below delay_max"):
        EnvConfig.make(delay=4, delay_model="geometric", delay_max=4)
    assert EnvConfig.make(delay=1.5, delay_model="geometric").delay == 1.5


def test_geometric_delay__has_the_configured_mean():
    d = DelayLine((40_000,), 2.0, "geometric", 16, np.random.default_rng(1)).delays()
    assert abs(d.mean() - 2.0) < 0.05 and d.min() == 0  # the bound moves the mean by 0.003


@pytest.mark.parametrize("delay, loss, want", [
    (0.0, 0.0, lambda t: 0),  # every message arrives the step it is sent
    (2.0, 0.0, lambda t: min(t + 1, 2)),  # nothing before t = 2, then the message of t - 2
    (0.0, 1.0, lambda t: t + 1),  # never anything
])
def test_pettingzoo__infos_carry_the_age_of_what_each_group_holds(delay, loss, want):
    from envs.warehouse_v0 import parallel_env

    env = parallel_env(n_robots=8, layout="wh20", groups=4, horizon=10, loss_p=loss, delay=delay)
    _, infos = env.reset(seed=0)
    for t in range(6):
        for agent, info in infos.items():
            own = env.groups[env.agent_ids[agent]]
            ages = np.asarray(info["message_age"])
            assert ages[own] == 0 and (np.delete(ages, own) == want(t)).all(), (t, agent, ages)
        _, _, _, _, infos = env.step(dict.fromkeys(env.agents, 4))
