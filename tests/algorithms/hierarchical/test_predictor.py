"""The GRU predictor: the loss counts lost messages only, the training unroll reproduces the
rollout's predictions, the loss falls on a lossy stream, snapping to free cells.

Runtime: about 10 s.
"""
from __future__ import annotations

import numpy as np
import torch

from algorithms.common.episodes import EpisodeBatch, batch_rng
from algorithms.common.execution import ActionChoice
from algorithms.hierarchical.messages import MSG_DIM, PRESENT
from algorithms.hierarchical.method import HierarchicalMethod
from algorithms.hierarchical.predictor import (
    GroupPredictor,
    SnapToFree,
    initial_state,
    prediction_error,
    predictor_loss,
    rollout_step,
)
from algorithms.hierarchical.training import predictor_loss_on, predictor_targets
from envs.config import EnvConfig
from envs.layouts import load_layout


def test_predictor_loss__ignores_delivered_links() -> None:
    g = torch.Generator().manual_seed(0)
    pred = torch.rand(2, 6, 3, 4, MSG_DIM, generator=g)
    target = torch.rand(2, 6, 3, 4, MSG_DIM, generator=g)
    target[..., PRESENT] = 1.0
    lost = torch.rand(2, 6, 3, generator=g) < 0.5
    slots = torch.ones(2, 6, 3, 4, dtype=torch.bool)
    base = predictor_loss(pred, target, lost, slots, 10.0)
    moved = pred.clone()
    moved[~lost] += 5.0  # change every prediction of a delivered message
    assert torch.equal(predictor_loss(moved, target, lost, slots, 10.0), base)
    moved = pred.clone()
    moved[lost] += 0.5  # change the predictions of lost messages
    assert not torch.allclose(predictor_loss(moved, target, lost, slots, 10.0), base)
    slots[..., -1] = False  # padding slots never count
    moved = pred.clone()
    moved[..., -1, :] += 5.0
    assert torch.equal(predictor_loss(moved, target, lost, slots, 10.0),
                       predictor_loss(pred, target, lost, slots, 10.0))


def test_prediction_error__absent_robot_counts_only_its_present_flag() -> None:
    target = torch.zeros(1, MSG_DIM)  # an absent robot: all zeros
    pred = torch.zeros(1, MSG_DIM)
    pred[0, :2] = 7.0  # any position
    pred[0, PRESENT] = 0.25
    assert torch.allclose(prediction_error(pred, target, torch.ones(1, dtype=torch.bool)), torch.tensor(0.0625))


def test_predictor__training_unroll_reproduces_the_rollout_predictions() -> None:
    """L_c computed by the batched training unroll (lost links only, checkpointed chunks)
    equals the loss of the predictions the rollout actually made on its lost links."""
    env = EnvConfig.make(n_robots=10, layout="tiny", horizon=25, loss_p=0.5)
    m = HierarchicalMethod(env, {"batch_episodes": 3}, seed=1)
    with torch.no_grad():
        state, _ = m.run(EpisodeBatch(env, 3, batch_rng(1, 0, 0), m.layout), ActionChoice.train(m.torch_gen))
        buf, gs = state.buffer, m.gs
        data = predictor_targets(m.gs, buf)
        fast = predictor_loss_on(m.predictor, data, chunk=4)
        # Replay the rollout's predictor from the stored messages and availabilities.
        nb = np.maximum(gs.neighbors, 0)
        slots = torch.from_numpy(gs.slot_valid[nb] & gs.link_valid[..., None])
        pstate, total = None, 0.0
        for t in range(buf.t):
            msgs, avail = buf.data["msgs"][t], buf.data["avail"][t]
            link = msgs[:, nb]
            if pstate is None:
                pstate = initial_state(m.predictor, link)
            m_hat = rollout_step(m.predictor, pstate, link, avail, msgs)
            lost = ~avail & gs.link_valid[None] & buf.running[t][:, None, None]
            err = prediction_error(torch.from_numpy(m_hat), torch.from_numpy(link), slots[None])
            total += float((err * torch.from_numpy(lost)).sum())
    assert data["lost"].sum() > 20
    assert abs(float(fast) - total / float(data["n_group_steps"])) < 1e-4 * max(1.0, total)


def synthetic_stream(rng: np.random.Generator, t_len: int = 24, batch: int = 16, n: int = 3) -> dict:
    """Two groups hearing each other (K = 1); robots move in a constant direction; each
    message is lost with probability 0.5."""
    z, k = 2, 1
    dirs = np.array([(-1, 0), (1, 0), (0, -1), (0, 1)])
    d = rng.integers(0, 4, size=(z, batch, n))
    start = rng.integers(30, 40, size=(z, batch, n, 2))
    t = np.arange(t_len)[None, :, None, None, None]
    pos = start[:, None] + t * dirs[d][:, None]  # (Z, T, B, n, 2)
    msgs = np.zeros((z, t_len, batch, n, MSG_DIM), np.float32)
    msgs[..., :2] = pos
    msgs[..., 2:7] = np.eye(5)[d][:, None]
    msgs[..., PRESENT] = 1.0
    avail = rng.random((z, t_len, batch, k)) < 0.5
    age = np.zeros(avail.shape, np.int64)
    last = -1 * np.ones((z, batch, k), np.int64)
    for s in range(t_len):
        age[:, s] = np.where(avail[:, s], 0, last + 1)
        last = age[:, s]
    link = msgs[::-1][:, :, :, None]  # group z hears the other group: (Z, T, B, K, n, D)
    tt = np.arange(t_len)[None, :, None, None] - age
    mem = link[np.arange(z)[:, None, None, None], tt, np.arange(batch)[None, None, :, None], 0][:, :, :, None]
    mem = mem.reshape(link.shape)
    return {
        "link": torch.from_numpy(np.ascontiguousarray(link)), "mem": torch.from_numpy(np.ascontiguousarray(mem)),
        "avail": torch.from_numpy(avail), "age": torch.from_numpy(age), "lost": torch.from_numpy(~avail),
        "own": torch.from_numpy(msgs), "slots": torch.ones(z, k, n, dtype=torch.bool),
        "n_group_steps": torch.tensor(float(z * t_len * batch)),
    }


def test_predictor__loss_falls_on_a_lossy_stream() -> None:
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    model = GroupPredictor(2, 2, (70, 70), hidden=32, embed=16)
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    held = synthetic_stream(np.random.default_rng(99))
    with torch.no_grad():
        before = float(predictor_loss_on(model, held, chunk=8))
    for _ in range(150):
        opt.zero_grad()
        predictor_loss_on(model, synthetic_stream(rng), chunk=8).backward()
        opt.step()
    with torch.no_grad():
        after = float(predictor_loss_on(model, held, chunk=8))
    assert after < 0.35 * before, (before, after)


def test_snap_to_free__nearest_free_cell() -> None:
    layout = load_layout("tiny")
    snap = SnapToFree(layout)
    cells = layout.cells
    assert (snap(cells.astype(np.float64)) == np.arange(layout.n_free)).all()
    h, w = layout.shape
    rc = np.stack(np.meshgrid(np.arange(h), np.arange(w), indexing="ij"), -1).reshape(-1, 2)
    got = layout.cells[snap(rc.astype(np.float64) + 0.3)]
    best = np.sqrt(((rc[:, None, :] - cells[None]) ** 2).sum(-1)).min(1)
    assert np.allclose(np.sqrt(((got - rc) ** 2).sum(-1)), best)
    assert snap(np.array([[-5.0, 100.0]])).shape == (1,)  # off the grid: clipped, then snapped
