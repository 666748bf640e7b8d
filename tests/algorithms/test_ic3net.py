"""IC3Net: averaged communication, the talk/silent gate, lossy links, payload, learning.

Runtime: about 3 s for the unit tests; the learning test about 15 s on one core.
"""
from __future__ import annotations

import numpy as np
import pytest
import torch

from algorithms.common.episodes import EpisodeBatch, batch_rng
from algorithms.common.execution import ARGMAX_CHOICE, ActionChoice
from algorithms.ic3net import IC3NetMethod, average_comm
from envs.config import EnvConfig
from tests.algorithms.learning import eval_success


def test_average_comm__matches_a_hand_computed_example() -> None:
    h = torch.tensor([[[1.0, 2.0], [3.0, 4.0], [5.0, 6.0], [7.0, 8.0]]])  # (1, 4, 2)
    links = torch.zeros(1, 4, 4, dtype=torch.bool)  # [sender, receiver]
    links[0, 0, 1] = links[0, 2, 1] = True  # robot 1 hears robots 0 and 2
    links[0, 1, 0] = True  # robot 0 hears robot 1
    # 3 robots alive (robot 3 has completed): divide by alive - 1 = 2, as the reference does,
    # whatever the number of robots actually heard.
    out = average_comm(h, links, torch.tensor([3]))
    expected = torch.tensor([[[1.5, 2.0], [3.0, 4.0], [0.0, 0.0], [0.0, 0.0]]])
    assert torch.equal(out, expected)
    # A single robot alive: the divisor is 1 (reference: only when alive > 1).
    assert torch.equal(average_comm(h, links, torch.tensor([1])), torch.tensor(
        [[[3.0, 4.0], [6.0, 8.0], [0.0, 0.0], [0.0, 0.0]]]))


def test_average_comm__batched_einsum_equals_a_per_pair_loop() -> None:
    gen = torch.Generator().manual_seed(0)
    h = torch.randn(3, 5, 4, generator=gen)
    links = torch.rand(3, 5, 5, generator=gen) < 0.5
    alive = torch.tensor([5, 4, 2])
    out = average_comm(h, links, alive)
    for b in range(3):
        for i in range(5):
            ref = sum(h[b, j] for j in range(5) if links[b, j, i]) / max(int(alive[b]) - 1, 1)
            assert torch.allclose(out[b, i], torch.as_tensor(ref) * torch.ones(4), atol=1e-6)


ENV = EnvConfig(n_robots=6, layout="tiny", horizon=15, groups=2, loss_p=0.0)


def rollout_logits(params: dict, env: EnvConfig = ENV, seed: int = 1) -> list[torch.Tensor]:
    """Action logits of every step of one sampled (training-mode) rollout."""
    m = IC3NetMethod(env, {"batch_episodes": 2, **params}, seed=seed)
    seen: list[torch.Tensor] = []
    m.policy.register_forward_hook(lambda mod, inp, out: seen.append(out[0].clone()))
    batch = EpisodeBatch(env, 2, batch_rng(0, 0, 0), m.layout)
    with torch.no_grad():
        m.run(batch, ActionChoice.train(m.torch_gen))
    return seen


def test_gate_closed_for_every_robot_acts_exactly_as_no_communication() -> None:
    silent = rollout_logits({"communicate": False})
    closed = rollout_logits({"gate": "closed"})
    talking = rollout_logits({"gate": "open"})
    assert len(silent) == len(closed) > 2
    assert all(torch.equal(a, b) for a, b in zip(silent, closed, strict=True))
    # The comparison can fail: with open gates the logits differ from step 1 on.
    assert torch.equal(silent[0], talking[0])  # nobody talks at t = 0
    assert not torch.equal(silent[1], talking[1])


def test_with_every_message_lost_no_message_is_ever_used() -> None:
    lossy = EnvConfig(**{**ENV.model_dump(), "loss_p": 1.0})
    silent = rollout_logits({"communicate": False}, env=lossy)
    talking_lost = rollout_logits({"gate": "open"}, env=lossy)
    assert all(torch.equal(a, b) for a, b in zip(silent, talking_lost, strict=True))


def test_links_combine_gates_liveness_and_loss() -> None:
    m = IC3NetMethod(EnvConfig(**{**ENV.model_dump(), "loss_p": 0.5}), {}, seed=0)
    batch = EpisodeBatch(m.env, 1, batch_rng(0, 0, 0), m.layout)
    state = m.begin(batch, ARGMAX_CHOICE)
    state.gate[:] = np.array([[1, 1, 1, 0, 1, 1]], dtype=bool)
    alive = np.array([[1, 1, 1, 1, 1, 0]], dtype=bool)
    links = m.links(state, alive)[0]
    talk = np.array([1, 1, 1, 0, 1, 0], dtype=bool)
    allowed = talk[:, None] & talk[None, :] & ~np.eye(6, dtype=bool)
    assert not (links & ~allowed).any()  # silent, completed and self links never carry
    assert 0 < links.sum() < allowed.sum()  # about half of the allowed links are lost
    # Payload counts transmissions (lost or not): H per open directed link.
    assert m.payload(state, alive)[0] == 4 * 3 * m.params.hidden


def test_payload_is_zero_while_every_gate_is_closed() -> None:
    m = IC3NetMethod(ENV, {"gate": "closed", "eval_chunk": 2}, seed=0)
    assert all(r["payload_scalars_per_step"] == 0 for r in m.evaluate(0))
    m = IC3NetMethod(ENV, {"gate": "open", "eval_chunk": 2}, seed=0)
    n = ENV.n_robots
    rows = m.evaluate(0)
    # t = 0 is silent; afterwards every alive pair talks (fewer as robots complete).
    assert all(0 < r["payload_scalars_per_step"] < n * (n - 1) * m.params.hidden for r in rows)


def test_update_replays_exactly_what_the_rollout_computed() -> None:
    m = IC3NetMethod(ENV, {"batch_episodes": 2}, seed=1)
    seen: list[tuple] = []
    hook = m.policy.register_forward_hook(lambda mod, inp, out: seen.append(out[:3]))
    batch = EpisodeBatch(ENV, 2, batch_rng(0, 0, 0), m.layout)
    with torch.no_grad():
        state, _ = m.run(batch, ActionChoice.train(m.torch_gen))
        hook.remove()
        data = {k: state.buffer.tensor(k) for k in state.buffer.data}
        hc = m.policy.initial_state(2, ENV.n_robots)
        assert state.buffer.t == len(seen) > 2
        for t, (logits, gates, values) in enumerate(seen):
            again, gates_again, values_again, hc = m.replay_step(data, t, hc)
            assert torch.equal(again, logits) and torch.equal(gates_again, gates)
            assert values is None and values_again is None  # the shared critic is the baseline


@pytest.mark.slow
def test_ic3net__learns_on_a_small_layout() -> None:
    env = EnvConfig(n_robots=4, layout="tiny", horizon=30, groups=2, loss_p=0.2)
    m = IC3NetMethod(env, {"batch_episodes": 8, "eval_chunk": 20}, seed=0)

    before = eval_success(m)
    for _ in range(150):
        m.train_iteration()
    after = eval_success(m)
    # Seed 0 on one torch thread (shared defaults, central critic): argmax success 0.08 -> 0.71.
    assert after >= before + 0.3, (before, after)


def test_chunk_replay__equals_step_by_step_forward_outputs_and_gradients() -> None:
    """``IC3NetPolicy.replay`` over a chunk (encoder and heads batched over time) against T
    calls of ``forward``: outputs and parameter gradients within float32 rounding (with the
    reference's per-robot value head, so the value output is covered too)."""
    m = IC3NetMethod(ENV, {"batch_episodes": 2, "action_path": True, "baseline": "per_robot"}, seed=3)
    batch = EpisodeBatch(ENV, 2, batch_rng(0, 0, 0), m.layout)
    with torch.no_grad():
        state, _ = m.run(batch, ActionChoice.train(m.torch_gen))
    data = {k: state.buffer.tensor(k) for k in state.buffer.data}
    t_used = state.buffer.t
    params = list(m.policy.parameters())

    def grads(outputs: tuple) -> list[torch.Tensor]:
        logits, gates, values = outputs
        loss = (torch.log_softmax(logits, -1)[..., 0] + gates[..., 1] + values.square()).sum()
        return list(torch.autograd.grad(loss, params, allow_unused=True))

    outs, hc = [], m.policy.initial_state(2, ENV.n_robots)
    for t in range(t_used):
        logits, gates, values, hc = m.replay_step(data, t, hc)
        outs.append((logits, gates, values))
    plain = tuple(torch.stack([o[i] for o in outs]) for i in range(3))
    sl = slice(0, t_used)
    logits, gates, values, hc2 = m.policy.replay(data["obs"][sl], data["mask"][sl], data["links"][sl],
                                                data["alive"][sl], m.policy.initial_state(2, ENV.n_robots))
    for a, b in zip((logits, gates, values), plain, strict=True):
        torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(hc2[0], hc[0], rtol=1e-5, atol=1e-5)
    for a, b in zip(grads((logits, gates, values)), grads(plain), strict=True):
        if a is not None or b is not None:
            torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-4)


def rolled_out(params: dict, seed: int = 3) -> tuple[IC3NetMethod, IC3NetMethod, object]:
    """A method after one training rollout, and a twin holding the same parameters."""
    env = EnvConfig(n_robots=5, layout="tiny", horizon=40, groups=2, loss_p=0.3)
    full = {"batch_episodes": 3, "detach_gap": 1000, "max_grad_norm": 1e9, **params}
    m = IC3NetMethod(env, full, seed=seed)
    if m.params.baseline == "per_robot":  # non-trivial running statistics, so denormalizing matters
        vn = m.policy.value_norm
        vn.mean.fill_(-20.0), vn.mean_sq.fill_(500.0), vn.weight.fill_(1.0)
    twin = IC3NetMethod(env, full, seed=seed)
    twin.load_state_dict(m.state_dict())
    with torch.no_grad():
        state, _ = m.run(EpisodeBatch(env, 3, batch_rng(0, 0, 1), m.layout), ActionChoice.train(m.torch_gen))
    return m, twin, state


@pytest.mark.parametrize("baseline", ["central", "per_robot"])
def test_update__gradient_is_reinforce_with_the_baseline_over_alive_robots(baseline: str) -> None:
    """The update's gradient equals the loss written out here from the stored rollout:
    -sum over alive robot-steps of A (log pi(u) + log pi(g)) / steps + value term - entropy,
    with A = (G_t - V) normalized: the team critic's V(X_t) (RMS, ``baseline="central"``) or
    the rollout's denormalized per-robot V^i (standardized, ``"per_robot"``)."""
    m, twin, state = rolled_out({"baseline": baseline, "entropy_coef": 0.01})
    buf = state.buffer
    data = {k: buf.tensor(k) for k in buf.data}
    running = torch.from_numpy(buf.running[: buf.t])
    done = data["obs"][..., 5] > 0.5  # the robot's own "done" feature
    active = (~done & running[..., None]).float()  # (T, B, N)
    assert 0 < float((done & running[..., None]).sum()), "some robots finish while episodes run"
    g = torch.flip(torch.cumsum(torch.flip(torch.from_numpy(buf.rewards[: buf.t]), [0]), 0), [0])
    n_steps, n_active = running.sum().float(), active.sum()
    # Replay with gradients on the twin (same parameters), full BPTT (detach_gap > T).
    hc = twin.policy.initial_state(*data["actions"].shape[1:])
    logps, ents, heads = [], [], []
    for t in range(buf.t):
        logits, gate_logits, v, hc = twin.replay_step(data, t, hc)
        la, lg = torch.log_softmax(logits, -1), torch.log_softmax(gate_logits, -1)
        logps.append(la.gather(-1, data["actions"][t][..., None])[..., 0]
                     + lg.gather(-1, data["gates"][t][..., None])[..., 0])
        ents.append(-(la.exp() * la).sum(-1))
        heads.append(v)
    logp, ent = torch.stack(logps), torch.stack(ents)
    if baseline == "central":
        with torch.no_grad():
            v_team = twin.critic(data["critic"], data["t_frac"])  # (T, B)
        adv = (g - v_team) * running
        adv = adv / torch.sqrt((adv**2).sum() / n_steps)
        adv = adv[..., None].expand_as(active)
        value_term = torch.zeros(())
    else:
        vn = twin.policy.value_norm
        mu, sigma = vn.stats()
        v_rob = torch.stack(heads).detach() * sigma + mu  # the rollout's V^i in return units
        adv = g[..., None] - v_rob
        mean = (adv * active).sum() / n_active
        adv = (adv - mean) / torch.sqrt((((adv - mean) * active) ** 2).sum() / n_active)
        targets = g[..., None].expand_as(active)
        vn.update(targets, active)
        value_term = twin.params.value_coef * (((torch.stack(heads) - vn.normalize(targets)) ** 2)
                                               * active).sum() / n_steps
    loss = -(adv * logp * active).sum() / n_steps + value_term - 0.01 * (ent * active).sum() / n_active
    loss.backward()
    m.update(state)
    for (name, a), b in zip(m.policy.named_parameters(), twin.policy.parameters(), strict=True):
        assert a.grad is not None and torch.allclose(a.grad, b.grad, rtol=1e-3, atol=1e-6), name


def test_per_robot_baseline__rollout_stores_values_in_return_units() -> None:
    m, _, state = rolled_out({"baseline": "per_robot"})
    seen: list[torch.Tensor] = []
    m.policy.register_forward_hook(lambda mod, inp, out: seen.append(out[2]))
    with torch.no_grad():
        state2, _ = m.run(EpisodeBatch(m.env, 3, batch_rng(0, 0, 1), m.layout), ActionChoice.train(m.torch_gen))
    mu, sigma = m.policy.value_norm.stats()
    assert float(mu) == -20.0
    stored = state2.buffer.tensor("values")
    assert torch.allclose(stored, torch.stack(seen[: stored.shape[0]]) * sigma + mu)


def test_options__reference_setting_uses_rmsprop_and_the_per_robot_head() -> None:
    ref = IC3NetMethod(ENV, {"baseline": "per_robot", "optimizer": "rmsprop"}, seed=0)
    assert isinstance(ref.optimizer, torch.optim.RMSprop) and ref.critic is None
    assert ref.policy.value_head is not None and "critic" not in ref.state_dict()
    shared = IC3NetMethod(ENV, {}, seed=0)
    assert isinstance(shared.optimizer, torch.optim.Adam) and shared.policy.value_head is None
    assert {"critic", "critic_opt"} <= set(shared.state_dict())


@pytest.mark.parametrize("delay, model, heard", [(0.0, "fixed", 0.8), (1.0, "fixed", 0.0), (2.0, "fixed", 0.0),
                                                 (2.0, "geometric", 0.8 / 3)])
def test_links__a_late_message_is_not_heard_and_still_counted_as_sent(delay: float, model: str,
                                                                      heard: float) -> None:
    """docs/decisions/0223: IC3Net hears only this step's vectors, so under a fixed delay
    d >= 1 it hears nothing (as at p = 1) and under a geometric delay of mean d the share
    (1 - p) / (1 + d) that arrives at once; payload counts what was sent, as at delay 0."""
    env = EnvConfig(**{**ENV.model_dump(), "loss_p": 0.2, "delay": delay, "delay_model": model})
    m = IC3NetMethod(env, {}, seed=0)
    batch = EpisodeBatch(m.env, 8, batch_rng(0, 0, 0), m.layout)
    state = m.begin(batch, ARGMAX_CHOICE)
    n = env.n_robots
    state.gate[:] = True
    alive = np.ones((8, n), dtype=bool)
    links = np.stack([m.links(state, alive) for _ in range(60)])
    share = links.sum() / (links.shape[0] * 8 * n * (n - 1))
    assert share == pytest.approx(heard, abs=0.03)
    assert (links == 0).all() if heard == 0 else share > 0
    assert m.payload(state, alive)[0] == n * (n - 1) * m.params.hidden
