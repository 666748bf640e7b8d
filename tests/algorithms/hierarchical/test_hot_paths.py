"""Optimized hierarchical hot paths against their plain formulas on the same inputs.

Exact where the arithmetic is unchanged (neighbour patches); float32 tolerance 1e-5
(relative, on outputs of order 1) where only the summation order changed (masked mean as
a matrix product, the local policy's head applied to the context once per row).
Runtime: about 2 s.
"""
from __future__ import annotations

import numpy as np
import torch

from algorithms.common.action_path import ACTION_GAIN
from algorithms.common.episodes import EpisodeBatch, batch_rng
from algorithms.common.execution import ActionChoice
from algorithms.hierarchical.group_layers import masked_mean
from algorithms.hierarchical.method import HierarchicalMethod
from algorithms.hierarchical.policies import LocalPolicy, neighbor_patches
from envs.config import EnvConfig
from envs.observations import PatchExtractor

TOL = dict(rtol=1e-5, atol=1e-5)


def plain_masked_mean(x: torch.Tensor, mask: torch.Tensor, dim: int) -> torch.Tensor:
    m = mask.to(x.dtype).unsqueeze(-1)
    return (x * m).sum(dim=dim) / m.sum(dim=dim).clamp_min(1.0)


def test_masked_mean__equals_the_masked_sum_including_empty_sets() -> None:
    torch.manual_seed(0)
    x = torch.randn(4, 6, 5, 3, 7, requires_grad=True)
    mask = torch.rand(4, 6, 5, 3) < 0.5
    mask[0, 0, 0] = False  # an empty set pools to zeros
    got = masked_mean(x, mask, dim=-2)
    want = plain_masked_mean(x, mask, dim=-2)
    torch.testing.assert_close(got, want, **TOL)
    assert torch.equal(got[0, 0, 0], torch.zeros(7))
    g1, = torch.autograd.grad(got.square().sum(), x)
    g2, = torch.autograd.grad(want.square().sum(), x)
    torch.testing.assert_close(g1, g2, **TOL)
    torch.testing.assert_close(masked_mean(x, mask, dim=2),  # another axis: the plain path
                               plain_masked_mean(x, mask, dim=2))


def test_masked_mean__without_a_graph_is_the_same_numbers_as_with_one() -> None:
    """Rollouts (no graph) skip the autograd Function; the pooled values are bit for bit
    the training pass's, and the empty set still pools to zeros."""
    torch.manual_seed(2)
    x = torch.randn(4, 6, 5, 11, 8)
    mask = torch.rand(4, 6, 5, 11) < 0.5
    mask[1, 2, 3] = False
    with_graph = masked_mean(x.clone().requires_grad_(True), mask, dim=-2)
    assert with_graph.grad_fn is not None
    for ctx in (torch.no_grad, torch.inference_mode):
        with ctx():
            got = masked_mean(x, mask, dim=-2)
        assert got.grad_fn is None and torch.equal(got, with_graph.detach())
    assert torch.equal(got[1, 2, 3], torch.zeros(8))


def test_masked_mean__gradient_is_bit_identical_to_autograds_bmm_backward() -> None:
    """The custom backward (mask x grad outer product) gives the very numbers autograd's
    backward of the forward's batched product gives, so training is unchanged bit for bit."""
    torch.manual_seed(1)
    x = torch.randn(3, 9, 4, 10, 16, requires_grad=True)
    m = (torch.rand(3, 9, 4, 10) < 0.6).to(x.dtype)
    g = torch.randn(3, 9, 4, 16)
    total = torch.bmm(m.reshape(-1, 1, 10), x.reshape(-1, 10, 16)).reshape(3, 9, 4, 16)
    want, = torch.autograd.grad(total / m.sum(-1, keepdim=True).clamp_min(1.0), x, g)
    got, = torch.autograd.grad(masked_mean(x, m.bool(), dim=-2), x, g)
    assert torch.equal(got, want)


def plain_local_logits(pol: LocalPolicy, robots, mask, ref) -> torch.Tensor:
    """The head on the concatenated (Z, M, n, 3H) input, as first written."""
    z, m, n, _ = robots.shape
    h = pol.enc(robots)
    pooled = plain_masked_mean(h, mask, dim=-2)
    table = pol.ref_embed.expand(z, -1, -1) if pol.ref_embed.shape[0] != z else pol.ref_embed
    e = torch.gather(table, 1, ref.reshape(z, m, 1).expand(z, m, table.shape[-1]))
    ctx = torch.cat([pooled, e], dim=-1).unsqueeze(2).expand(z, m, n, -1)
    logits = pol.head(torch.cat([h, ctx], dim=-1))
    phi = robots[..., pol.action_idx].transpose(-1, -2)
    return logits + ACTION_GAIN * (phi * pol.action_w).sum(-1)


def test_local_policy_head__equals_the_concatenated_head_forward_and_backward() -> None:
    for shared in (4, 1):
        torch.manual_seed(1)
        pol = LocalPolicy(shared, 4, 61, 32, 8, obs_radius=2)
        with torch.no_grad():
            pol.action_w.normal_()
        robots = torch.randn(4, 9, 7, 61)
        mask = torch.rand(4, 9, 7) < 0.8
        ref = torch.randint(0, 8, (4, 9))
        amask = torch.ones(4, 9, 7, 5, dtype=torch.bool)
        got = pol(robots, mask, ref, amask)
        want = torch.log_softmax(plain_local_logits(pol, robots, mask, ref), dim=-1)
        torch.testing.assert_close(got, want, **TOL)
        g1 = torch.autograd.grad(got[..., 0].sum(), list(pol.parameters()), allow_unused=True)
        g2 = torch.autograd.grad(want[..., 0].sum(), list(pol.parameters()), allow_unused=True)
        for a, b in zip(g1, g2, strict=True):
            if a is not None or b is not None:
                torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-5)


def plain_neighbor_patches(patch, gs, cells, present, heading) -> np.ndarray:
    """A fresh zero grid and np.add.at per call, as first written."""
    b, z = cells.shape[:2]
    size = patch.pad_obs.size
    plane = b * z * size
    rows = ((np.arange(b)[:, None] * z + np.arange(z)[None, :]) * size)[:, :, None, None]
    flat = np.concatenate([(rows + patch.center[cells])[present],
                           (rows + patch.center[heading])[present] + plane])
    grid = np.zeros(2 * plane, dtype=np.int32)
    np.add.at(grid, flat, 1)
    row = (np.arange(b)[:, None] * z + gs.groups[None, :]) * size
    idx = (row + patch.center[patch.core.pos])[..., None] + patch.offsets
    return np.minimum(grid[np.concatenate([idx, idx + plane], axis=-1)], 255).astype(np.uint8)


def test_neighbor_patches__equal_the_plain_counts_call_after_call() -> None:
    env = EnvConfig.make(n_robots=20, layout="wh20", horizon=10, loss_p=0.5)
    m = HierarchicalMethod(env, {}, seed=0)
    batch = EpisodeBatch(env, 3, batch_rng(0, 0, 0), m.layout)
    patch = PatchExtractor(batch.core, 2)
    rng = np.random.default_rng(0)
    shape = (3, env.groups, m.gs.neighbors.shape[1], m.gs.n_slots)
    for _ in range(20):
        # Crowded draws: many robots share cells, so counts above 1 occur.
        cells = rng.integers(0, 40, size=shape)
        heading = m.layout.next_cell[cells, rng.integers(0, 5, size=shape)]
        present = rng.random(shape) < 0.8
        got = neighbor_patches(patch, m.gs, cells, present, heading)
        want = plain_neighbor_patches(patch, m.gs, cells, present, heading)
        assert want.max() > 1
        np.testing.assert_array_equal(got, want)
        batch.core.step(rng.integers(0, 5, size=(3, 20)))
    # Counts above 255 saturate (300 senders' robots drawn on the cells around robot 0).
    shape = (*shape[:3], 300)
    cells = np.broadcast_to(patch.core.pos[:, None, None, :1], shape) + rng.integers(0, 2, size=shape)
    heading = m.layout.next_cell[cells, 4]
    present = np.ones(shape, bool)
    got = neighbor_patches(patch, m.gs, cells, present, heading)
    want = plain_neighbor_patches(patch, m.gs, cells, present, heading)
    assert want.max() == 255
    np.testing.assert_array_equal(got, want)


def test_predictor_norm__equals_dividing_the_positions_alone() -> None:
    """``_norm`` divides every column by (H, W, 1, ..., 1): bit for bit the positions
    divided and the rest copied (signed zeros included)."""
    from algorithms.hierarchical.messages import POS
    from algorithms.hierarchical.predictor import GroupPredictor

    model = GroupPredictor(4, 4, (33, 161))
    msg = torch.randn(4, 3, 2, 25, 8) * 50
    msg[0, 0, 0, 0] = -0.0
    want = torch.cat([msg[..., POS] / model.scale, msg[..., POS.stop:]], dim=-1)
    got = model._norm(msg)
    assert torch.equal(got, want) and torch.equal(torch.signbit(got), torch.signbit(want))


def plain_predictor_loss(model, data: dict) -> torch.Tensor:
    """L_c by the plainest unroll: encode every step, GRU step by step on x_t, decode every
    link, loss on the lost ones (no chunks, no checkpoints, no padding of lost links)."""
    from algorithms.hierarchical.predictor import predictor_loss

    z, t_used, b, k = data["avail"].shape
    avail_f = data["avail"].unsqueeze(-1).unsqueeze(-1).to(torch.float32)

    def rows(a: torch.Tensor) -> torch.Tensor:
        return a.reshape(z, -1, *a.shape[3:])

    x = model.encode(rows(data["link"] * avail_f), rows(data["avail"]), rows(data["age"]), rows(data["own"]))
    x = x.reshape(z, t_used, b, k, -1)
    h, hs = torch.zeros(z, b, k, model.hidden), []
    for t in range(t_used):
        h = model.step(x[:, t], h)
        hs.append(h)
    pred = model.decode(torch.stack(hs, dim=1), data["mem"], data["age"])
    return predictor_loss(pred, data["link"], data["lost"], data["slots"][:, None, None], data["n_group_steps"])


def test_predictor_loss__equals_the_plain_unroll_loss_and_gradients() -> None:
    """predictor_loss_on (input gates of every step in one matmul, lost links only,
    checkpointed chunks) against the plain unroll: loss and gradients within float32."""
    from algorithms.hierarchical import training

    env = EnvConfig.make(n_robots=12, layout="wh20", horizon=30, loss_p=0.5)
    m = HierarchicalMethod(env, {"batch_episodes": 2}, seed=0)
    batch = EpisodeBatch(env, 2, batch_rng(0, 0, 0), m.layout)
    with torch.no_grad():
        state, _ = m.run(batch, ActionChoice.train(m.torch_gen))
    data = training.predictor_targets(m.gs, state.buffer)
    params = list(m.predictor.parameters())
    fast = training.predictor_loss_on(m.predictor, data, chunk=7)
    plain = plain_predictor_loss(m.predictor, data)
    assert float(plain) > 0
    torch.testing.assert_close(fast, plain, rtol=1e-5, atol=1e-6)
    g_fast = torch.autograd.grad(fast, params)
    g_plain = torch.autograd.grad(plain, params)
    for a, b in zip(g_fast, g_plain, strict=True):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-6)


def test_float16_rounding__torch_gives_numpys_values_bit_for_bit() -> None:
    """The rollout rounds the robot features to float16 with torch (numpy's astype is 15x
    slower); both must give the same bits: normal, subnormal, overflowing and special values."""
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.normal(size=20_000) * 3, rng.normal(size=5_000) * 1e-6,
                        rng.normal(size=5_000) * 1e5, [np.nan, np.inf, -np.inf, -0.0, 65504, 65520]]).astype(np.float32)
    with np.errstate(over="ignore"):
        want = x.astype(np.float16)
    got = torch.from_numpy(x).to(torch.float16).numpy()
    assert got.dtype == np.float16 and np.array_equal(got.view(np.uint16), want.view(np.uint16))
