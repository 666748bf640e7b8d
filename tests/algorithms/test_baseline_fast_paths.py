"""The baselines' in-place rollout paths equal the plain formulas exactly (bit for bit).

The decentralized baseline writes its observations, masks and critic inputs straight into
the rollout buffer's row, and ``AllToAllBoard`` keeps narrow integer arrays; these tests
run the optimized path and the plain one on the same inputs. Runtime: about 2 s.
"""
from __future__ import annotations

import numpy as np
import pytest
import torch

from algorithms.common.all_to_all import AllToAllBoard
from algorithms.common.episodes import EpisodeBatch, batch_rng
from algorithms.common.execution import ActionChoice
from algorithms.common.robot_obs import (
    action_mask,
    action_mask_into,
    local_view,
    local_view_into,
    own_history,
    own_history_into,
)
from algorithms.common.trainer import critic_features, critic_inputs
from algorithms.decentralized import DecentralizedMethod
from envs.channel import LossProcess
from envs.config import EnvConfig
from envs.observations import PatchExtractor


def plain_critic_features(core) -> np.ndarray:
    """``critic_features`` as first written (one concatenate)."""
    h, w = core.layout.shape
    scale = np.array([h, w], dtype=np.float32)
    rc = core.layout.cells[core.pos].astype(np.float32) / scale
    grc = core.layout.cells[core.goal].astype(np.float32) / scale
    dist = (np.minimum(core.dist, h * w) / float(h + w)).astype(np.float32)[..., None]
    done = core.done.astype(np.float32)[..., None]
    return np.concatenate([rc, grc, dist, done], axis=-1)


def test_into_helpers__equal_the_allocating_ones_bit_for_bit() -> None:
    env = EnvConfig.make(n_robots=30, layout="wh20", horizon=30, loss_p=0.3, on_goal="remove")
    batch = EpisodeBatch(env, 3, batch_rng(0, 0, 1))
    core, rng = batch.core, np.random.default_rng(0)
    for radius in (1, 2, 3):
        patch = PatchExtractor(core, radius)
        for _ in range(6):
            collided = rng.random(core.pos.shape) < 0.2
            lv = local_view(core, patch)
            out = np.full(lv.shape, np.nan, dtype=np.float32)
            local_view_into(core, patch, out)
            assert out.tobytes() == lv.tobytes()
            hist = np.full((*core.pos.shape, 6), np.nan, dtype=np.float32)
            own_history_into(core, collided, hist)
            assert hist.tobytes() == own_history(core, collided).tobytes()
            mask = np.zeros((*core.pos.shape, 5), dtype=bool)
            action_mask_into(core, mask)
            assert np.array_equal(mask, action_mask(core))
            assert critic_features(core).tobytes() == plain_critic_features(core).tobytes()
            assert critic_inputs(core, 30)["critic"].tobytes() == plain_critic_features(core).tobytes()
            core.step(rng.integers(0, 5, size=core.pos.shape))


def test_board__int32_positions_give_the_same_messages_and_maps_as_int16() -> None:
    """The board stores positions as int16 when the layout allows (every shipped layout);
    the int32 branch of larger layouts receives and encodes alike."""
    env = EnvConfig.make(n_robots=16, layout="wh20", horizon=40, loss_p=0.4, on_goal="remove")
    batch = EpisodeBatch(env, 2, batch_rng(0, 0, 2))
    narrow = AllToAllBoard(batch.core, LossProcess.from_config((2, 16, 16), env, batch_rng(5, 0, 0)), 2)
    wide = AllToAllBoard(batch.core, LossProcess.from_config((2, 16, 16), env, batch_rng(5, 0, 0)), 2)
    assert narrow.pos.dtype == np.int16
    wide.pos = wide.pos.astype(np.int32)
    rng = np.random.default_rng(1)
    for _ in range(20):
        assert np.array_equal(narrow.receive(), wide.receive())
        for name in ("pos", "ctl", "age"):
            assert np.array_equal(getattr(narrow, name), getattr(wide, name))
        assert narrow.features().tobytes() == wide.features().tobytes()
        batch.core.step(rng.integers(0, 5, size=(2, 16)))


def test_decentralized__buffer_rows_equal_the_plain_observation() -> None:
    """Observations written into the buffer row equal the plain concatenation of the
    local view, own history and message maps; masks and critic inputs alike."""
    env = EnvConfig.make(n_robots=12, layout="wh20", horizon=15, loss_p=0.3)
    m = DecentralizedMethod(env, {"batch_episodes": 2}, seed=1)
    batch = EpisodeBatch(env, 2, batch_rng(0, 0, 4), m.layout)
    choice = ActionChoice.train(m.torch_gen)
    with torch.no_grad():
        state = m.begin(batch, choice)
        while batch.running:
            core, t = batch.core, state.buffer.t
            collided = state.collided.copy()
            dec = m.decide(batch, state, choice)
            plain = np.concatenate([local_view(core, state.patch), own_history(core, collided),
                                    state.board.features()], axis=-1)
            assert state.buffer.data["obs"][t].tobytes() == plain.tobytes()
            assert np.array_equal(state.buffer.data["mask"][t], action_mask(core))
            inputs = critic_inputs(core, env.horizon)
            assert state.buffer.data["critic"][t].tobytes() == inputs["critic"].tobytes()
            assert state.buffer.data["t_frac"][t].tobytes() == inputs["t_frac"].tobytes()
            m.observe(batch, state, core.step(dec.actions))


def test_decentralized_actor__rollout_path_equals_the_autograd_path_bit_for_bit() -> None:
    from algorithms.base import masked_logits
    from algorithms.decentralized import DecentralizedActor

    torch.manual_seed(0)
    for action_path in (True, False):
        actor = DecentralizedActor(142, 64, 2, action_path)
        if action_path:
            with torch.no_grad():
                actor.path.weight.normal_()
        obs = torch.rand(3, 17, 142)
        mask = torch.rand(3, 17, 5) > 0.3
        plain = actor.net(obs)
        if action_path:  # the path as first written: advanced indexing
            phi = obs[..., actor.path.index].transpose(-1, -2)
            plain = plain + 10.0 * (phi * actor.path.weight).sum(-1)
        plain = masked_logits(plain, mask)
        assert torch.equal(actor(obs, mask), plain)  # grad mode: the plain ops
        with torch.inference_mode():
            assert torch.equal(actor(obs, mask), plain.detach())



def test_decentralized_actor__kept_activations_give_the_re_forward_gradients_bit_for_bit() -> None:
    """The update's gradients from the rollout's kept hidden activations
    (``logits_from_hidden`` + ``hidden_backward``) equal autograd's through a full
    re-forward, summed over several chunks (rows of a (B, N) rollout batch, gathered)."""
    from algorithms.decentralized import DecentralizedActor

    torch.manual_seed(1)
    actor = DecentralizedActor(142, 64, 2, True)
    with torch.no_grad():
        actor.path.weight.normal_()
    obs = torch.rand(4, 3, 50, 142)  # (T, B, N, F): one rollout step per t
    mask = torch.rand(4, 3, 50, 5) > 0.3
    hidden = torch.empty(2, 4, 3, 50, 64)
    with torch.inference_mode():
        for t in range(4):
            actor.rollout_logits(obs[t], mask[t], (hidden[0, t], hidden[1, t]))
    rows = torch.rand(4, 3, 50) < 0.8
    o, m, h0, h1 = obs[rows], mask[rows], hidden[0][rows], hidden[1][rows]
    weight = torch.randn(o.shape[0])

    def grads(kept: bool) -> list[torch.Tensor]:
        actor.zero_grad()
        for lo in range(0, o.shape[0], 97):  # uneven chunks
            sl = slice(lo, lo + 97)
            if kept:
                kept = (h0[sl], h1[sl].clone().requires_grad_())
                logits = actor.logits_from_hidden(o[sl], kept[1], m[sl])
            else:
                logits = actor(o[sl], m[sl])
            (weight[sl] * torch.log_softmax(logits, -1).amax(-1)).sum().backward()
            if kept:
                actor.hidden_backward(o[sl], kept)
        return [q.grad.clone() for q in actor.parameters()]

    for plain, fast in zip(grads(False), grads(True), strict=True):
        assert torch.equal(plain, fast) and plain.numpy().tobytes() == fast.numpy().tobytes()

def test_central_critic__sum_over_n_equals_the_mean_with_the_same_gradients() -> None:
    from algorithms.common.trainer import CentralCritic

    torch.manual_seed(0)
    critic = CentralCritic(32)
    robots, t_frac = torch.rand(7, 3, 13, 6), torch.rand(7, 3)
    weights = torch.randn(7, 3)

    def grads(forward) -> tuple[torch.Tensor, list[torch.Tensor]]:
        critic.zero_grad()
        v = forward(robots, t_frac)
        (v * weights).sum().backward()
        return v.detach(), [q.grad.clone() for q in critic.parameters()]

    def plain(x, tf):  # the mean as first written
        pooled = critic.phi(x).mean(dim=-2)
        done = x[..., 5].mean(dim=-1, keepdim=True)
        return critic.rho(torch.cat([pooled, tf[..., None], done], dim=-1)).squeeze(-1)

    (v0, g0), (v1, g1) = grads(plain), grads(critic)
    assert torch.equal(v0, v1)
    assert all(torch.equal(a, b) for a, b in zip(g0, g1, strict=True))


def test_average_comm__bmm_equals_the_einsum_bit_for_bit() -> None:
    from algorithms.ic3net import average_comm

    gen = torch.Generator().manual_seed(0)
    for n in (1, 2, 9, 40):
        links = torch.rand(3, n, n, generator=gen) < 0.6
        h = torch.randn(3, n, 16, generator=gen)
        alive = torch.tensor([n, max(n - 1, 0), 1])
        denom = torch.where(alive > 1, alive - 1, torch.ones_like(alive)).float()
        plain = torch.einsum("bji,bjh->bih", links.float(), h) / denom[:, None, None]
        assert torch.equal(average_comm(h, links, alive), plain)
        assert torch.equal(average_comm(h, links.float(), alive), plain)


def test_ic3net__buffer_rows_equal_the_plain_inputs() -> None:
    """The rollout writes observations, masks, links and critic inputs into the buffer
    row; they equal the plain concatenation and link formula of the same step."""
    from algorithms.ic3net import IC3NetMethod

    env = EnvConfig.make(n_robots=10, layout="wh20", horizon=15, loss_p=0.3)
    m = IC3NetMethod(env, {"batch_episodes": 2}, seed=1)
    batch = EpisodeBatch(env, 2, batch_rng(0, 0, 4), m.layout)
    choice = ActionChoice.train(m.torch_gen)
    with torch.no_grad():
        state = m.begin(batch, choice)
        while batch.running:
            core, t, buf = batch.core, state.buffer.t, state.buffer
            collided, gate = state.collided.copy(), state.gate.copy()
            twin = np.random.Generator(np.random.PCG64())
            twin.bit_generator.state = state.loss.process.rng.bit_generator.state
            delivered = twin.random(state.loss.process.shape) >= state.loss.process.p  # this step's draw
            dec = m.decide(batch, state, choice)
            talk = gate & ~core.done
            links = talk[:, :, None] & talk[:, None, :] & delivered & ~np.eye(10, dtype=bool)
            assert np.array_equal(buf.data["links"][t], links)
            plain = np.concatenate([local_view(core, state.patch), own_history(core, collided)], axis=-1)
            assert buf.data["obs"][t].tobytes() == plain.tobytes()
            assert np.array_equal(buf.data["mask"][t], action_mask(core))
            assert buf.data["critic"][t].tobytes() == critic_inputs(core, env.horizon)["critic"].tobytes()
            m.observe(batch, state, core.step(dec.actions))


def test_multinomial_one__equals_torch_multinomial_samples_and_generator_state() -> None:
    from algorithms.common.execution import multinomial_one, sample_categorical

    logits = torch.randn(500, 5, generator=torch.Generator().manual_seed(3)) * 3
    logits[::3, 0] = -1e9  # masked actions
    probs = torch.softmax(logits.double(), dim=-1)
    a, b = torch.Generator().manual_seed(7), torch.Generator().manual_seed(7)
    for _ in range(20):
        assert torch.equal(multinomial_one(probs, a), torch.multinomial(probs, 1, generator=b))
        assert torch.equal(a.get_state(), b.get_state())
    for temperature in (1.0, 0.5, 2.0):  # sample_categorical as first written
        flat = logits.reshape(-1, 5).double()
        plain = torch.multinomial(torch.softmax(flat / temperature, dim=-1), 1, generator=b).reshape(-1)
        assert torch.equal(sample_categorical(logits, temperature, a), plain)
    bad = probs.clone()
    bad[4, 2] = float("nan")
    with pytest.raises(RuntimeError):
        multinomial_one(bad, a)
