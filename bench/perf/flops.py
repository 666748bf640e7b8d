"""How close a method's training is to what this machine's arithmetic allows.

``matmul_profile`` runs one training iteration of a method under the torch profiler
(``with_flops``) and sums the floating-point operations of its matrix products (``aten::mm``,
``addmm``, ``bmm``, ``baddbmm``: forward and backward, rollout and update), grouped by input
shape. ``shape_peak`` times those same products alone, back to back, at the same shapes (the
best this iteration's matmuls could do on this core: small shapes are overhead-bound), and
``large_peak`` a large square product (the core's arithmetic peak), in float32 and in
bfloat16 (``machine_peaks``: the machine measured in the same run, not a quoted figure).
``matmul_rates`` turns them into FLOP/s: achieved = matmul FLOP per env-step x the
method's measured env-steps/s (measured without the profiler), and its fraction of each
peak. Everything on one torch thread and in process CPU time (one dedicated core, as the
shared machine's other load would otherwise count against us); the networks run in float32.
"""
from __future__ import annotations

import time
from typing import Any

import torch

from algorithms.registry import method_class
from envs.config import EnvConfig

MATMUL_OPS = ("aten::mm", "aten::addmm", "aten::bmm", "aten::baddbmm")
TOP_SHAPES = 40  # shapes timed for the same-shape peak (the ones with the most FLOP)
LARGE = 1024  # side of the square product for the large-shape peak


def matmul_profile(method: str, n_robots: int, layout: str, horizon: int = 200, batch_episodes: int = 8,
                   loss_p: float = 0.2, seed: int = 0) -> dict[str, Any]:
    """Matmul FLOP of one training iteration (after one warm-up) and its shapes:
    ``{"flops", "env_steps", "shapes": [(op, input_shapes, calls, flops), ...]}``."""
    torch.set_num_threads(1)
    env = EnvConfig.make(n_robots=n_robots, layout=layout, horizon=horizon, loss_p=loss_p,
                         groups=min(4, n_robots))
    m = method_class(method)(env, {"batch_episodes": batch_episodes}, seed=seed)
    m.train_iteration()
    rows, shapes = count_matmuls(m.train_iteration)
    return {"flops": sum(s[3] for s in shapes), "env_steps": int(sum(r["steps"] for r in rows)),
            "shapes": shapes}


def count_matmuls(fn: Any) -> tuple[Any, list[tuple[str, list[list[int]], int, float]]]:
    """``fn()``'s result and its matrix products as (op, input shapes, calls, FLOP), most
    FLOP first (torch profiler, ``with_flops``: 2 m k n per product)."""
    from torch.profiler import ProfilerActivity, profile

    with profile(activities=[ProfilerActivity.CPU], with_flops=True, record_shapes=True) as prof:
        out = fn()
    shapes = [(e.key, [list(s) for s in e.input_shapes], int(e.count), float(e.flops))
              for e in prof.key_averages(group_by_input_shape=True) if e.key in MATMUL_OPS and e.flops]
    return out, sorted(shapes, key=lambda s: -s[3])


def _operands(op: str, shapes: list[list[int]]) -> tuple[Any, tuple[torch.Tensor, ...]]:
    g = torch.Generator().manual_seed(0)

    def t(shape: list[int]) -> torch.Tensor:
        return torch.randn(*shape, generator=g) if shape else torch.tensor(1.0)

    if op == "aten::mm":
        return torch.mm, (t(shapes[0]), t(shapes[1]))
    if op == "aten::bmm":
        return torch.bmm, (t(shapes[0]), t(shapes[1]))
    if op == "aten::addmm":
        return torch.addmm, (t(shapes[0]), t(shapes[1]), t(shapes[2]))
    return torch.baddbmm, (t(shapes[0]), t(shapes[1]), t(shapes[2]))


def seconds_per_call(fn: Any, args: tuple[torch.Tensor, ...], min_s: float = 0.02) -> float:
    """Process CPU seconds of one call of ``fn(*args)`` (repeated for at least ``min_s``)."""
    fn(*args)
    reps, spent = 1, 0.0
    while True:
        t0 = time.process_time()
        for _ in range(reps):
            fn(*args)
        spent = time.process_time() - t0
        if spent >= min_s:
            return spent / reps
        reps *= 4


def shape_peak(shapes: list[tuple[str, list[list[int]], int, float]], top: int = TOP_SHAPES) -> dict[str, float]:
    """FLOP/s of the iteration's own matmuls run alone at their shapes: the ``top`` shapes
    with the most FLOP, their FLOP over their calls' standalone time; ``coverage`` = the
    share of the iteration's matmul FLOP those shapes hold."""
    torch.set_num_threads(1)
    total = sum(s[3] for s in shapes) or 1.0
    flops = secs = 0.0
    with torch.no_grad():
        for op, shape, calls, fl in shapes[:top]:
            fn, args = _operands(op, shape)
            secs += calls * seconds_per_call(fn, args)
            flops += fl
    return {"flops_per_s": flops / secs if secs else float("nan"), "coverage": flops / total}


def large_peak(n: int = LARGE, dtype: torch.dtype = torch.float32, repeats: int = 3) -> float:
    """FLOP/s of an n x n product in ``dtype`` on one thread (the core's arithmetic peak
    for that type): the best of ``repeats`` timings, each at least 0.2 CPU seconds (the
    least disturbed one: CPU time still counts a busy neighbour's cache and memory use)."""
    torch.set_num_threads(1)
    a, b = torch.randn(n, n).to(dtype), torch.randn(n, n).to(dtype)
    with torch.no_grad():
        return max(2.0 * n ** 3 / seconds_per_call(torch.mm, (a, b), min_s=0.2) for _ in range(max(repeats, 1)))


PEAK_DTYPES = {"fp32": torch.float32, "bf16": torch.bfloat16}


def machine_peaks(n: int = LARGE, repeats: int = 3) -> dict[str, float]:
    """This core's matmul peaks measured now, one per type of ``PEAK_DTYPES`` (FLOP/s):
    the fp32 the networks run in, and bf16 (AVX-512 BF16 or AMX where the CPU has them;
    2.5x the fp32 rate on the 2-core EPYC VM of 2026-12-06)."""
    return {name: large_peak(n, dtype, repeats) for name, dtype in PEAK_DTYPES.items()}


def matmul_rates(method: str, n_robots: int, layout: str, env_steps_per_s_cpu: float, peak_large: float,
                 horizon: int = 200, batch_episodes: int = 8, peak_bf16: float | None = None,
                 ) -> dict[str, float]:
    """Columns for ``bench perf --suite train``: matmul GFLOP per env-step, achieved
    GFLOP/s at the measured rate, the peaks (same shapes, large fp32 and, when given,
    large bf16, all measured in the same run) and the fractions of them."""
    prof = matmul_profile(method, n_robots, layout, horizon=horizon, batch_episodes=batch_episodes)
    per_step = prof["flops"] / max(prof["env_steps"], 1)
    achieved = per_step * env_steps_per_s_cpu
    same = shape_peak(prof["shapes"])
    return {
        "matmul_mflop_per_step": per_step / 1e6,
        "matmul_gflops_cpu": achieved / 1e9,
        "peak_same_shapes_gflops": same["flops_per_s"] / 1e9,
        "same_shapes_coverage": same["coverage"],
        "peak_large_gflops": peak_large / 1e9,
        "frac_of_same_shape_peak": achieved / same["flops_per_s"],
        "frac_of_large_peak": achieved / peak_large,
        **({} if peak_bf16 is None else {"peak_large_bf16_gflops": peak_bf16 / 1e9,
                                          "frac_of_bf16_peak": achieved / peak_bf16}),
    }
