"""bench perf --suite train's arithmetic columns: matmul FLOP counted by the profiler, the
same products re-run alone at their shapes, and the fractions of the peaks (no timing asserted)."""
from __future__ import annotations

import math

import torch

from bench.perf.flops import PEAK_DTYPES, _operands, count_matmuls, machine_peaks, matmul_rates, shape_peak


def test_count_matmuls__a_linear_layer_forward_and_backward_is_three_products_of_2mkn() -> None:
    lin = torch.nn.Linear(16, 8)
    x = torch.randn(5, 16, requires_grad=True)
    _, shapes = count_matmuls(lambda: lin(x).sum().backward())
    assert sum(s[3] for s in shapes) == 3 * 2 * 5 * 16 * 8  # y = xW, dL/dx, dL/dW
    assert {s[0] for s in shapes} == {"aten::addmm", "aten::mm"}


def test_shape_peak__replays_each_recorded_product_with_the_same_shapes_and_flop() -> None:
    a, b, c = torch.randn(3, 4, 5), torch.randn(3, 5, 6), torch.randn(3, 1, 6)
    _, shapes = count_matmuls(lambda: (torch.bmm(a, b), torch.baddbmm(c, a, b), torch.mm(a[0], b[0]),
                                       torch.addmm(c[0, 0], a[0], b[0])))
    for op, shape, calls, flops in shapes:
        fn, args = _operands(op, shape)
        assert [list(t.shape) for t in args] == shape[:len(args)] and all(s == [] for s in shape[len(args):])
        _, again = count_matmuls(lambda fn=fn, args=args: fn(*args))
        assert again == [(op, shape, 1, flops / calls)]
    peak = shape_peak(shapes)
    assert peak["coverage"] == 1.0 and peak["flops_per_s"] > 0


def test_matmul_rates__fractions_are_the_achieved_rate_over_each_peak() -> None:
    r = matmul_rates("decentralized", 4, "tiny", env_steps_per_s_cpu=1000.0, peak_large=1e10, horizon=6,
                     batch_episodes=1, peak_bf16=4e10)
    achieved = r["matmul_mflop_per_step"] * 1e6 * 1000.0
    assert math.isclose(r["matmul_gflops_cpu"], achieved / 1e9)
    assert math.isclose(r["frac_of_large_peak"], achieved / 1e10)
    assert math.isclose(r["frac_of_bf16_peak"], achieved / 4e10) and r["peak_large_bf16_gflops"] == 40.0
    assert math.isclose(r["frac_of_same_shape_peak"], achieved / (r["peak_same_shapes_gflops"] * 1e9))
    assert r["matmul_mflop_per_step"] > 0 and 0 < r["same_shapes_coverage"] <= 1


def test_machine_peaks__one_rate_per_type_each_the_best_of_its_repeats(monkeypatch) -> None:
    """fp32 and bf16 are both timed, in their own dtype, and each peak is the fastest repeat."""
    import bench.perf.flops as flops

    seen: list[torch.dtype] = []
    times = iter([4.0, 1.0, 2.0, 8.0, 2.0, 4.0])  # seconds per product: best 1.0 (fp32), 2.0 (bf16)

    def fake(fn, args, min_s=0.02):
        seen.append(args[0].dtype)
        return next(times)

    monkeypatch.setattr(flops, "seconds_per_call", fake)
    peaks = machine_peaks(n=8, repeats=3)
    assert set(peaks) == set(PEAK_DTYPES) == {"fp32", "bf16"}
    assert seen == [torch.float32] * 3 + [torch.bfloat16] * 3
    assert peaks == {"fp32": 2.0 * 8**3 / 1.0, "bf16": 2.0 * 8**3 / 2.0}
