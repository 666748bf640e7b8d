"""The device path (algorithms/common/device.py): ``Method(..., device=)`` places the networks,
optimizers and update tensors on a device; cpu (the default) is unchanged.

No CUDA here: the device runs use ``fake_cuda`` (tests/algorithms/fake_device.py), a CUDA
device simulated on the CPU that raises wherever real CUDA would (host and device tensors in
one kernel, a host generator drawing into a device tensor, ``numpy()`` of a device tensor),
backward passes and optimizer steps included. Its numbers are the CPU's, so every learned
method, under each training protocol and the variants scripts/train_hashes.py fingerprints,
must give bit for bit the CPU run's rows, evaluation and parameters. The real accelerator's
check is scripts/device_check.py."""
from __future__ import annotations

import copy
import json
from typing import Any

import pytest
import torch

from algorithms.common.device import check_device, host_tree, resolve_device
from algorithms.common.seed_stack import train_stacked
from algorithms.registry import method_class
from envs.config import EnvConfig
from envs.errors import BenchError
from tests.algorithms.fake_device import fake_cuda

# The configurations of scripts/train_hashes.py (its code paths), at a tiny size.
CASES: list[tuple[str, dict[str, Any]]] = [
    ("hierarchical", {}),
    ("hierarchical", {"share_params": True, "fallback": "per_robot", "resample_on_fallback": True}),
    ("hierarchical", {"messages": "oracle", "ref_hold": 3}),
    ("hierarchical", {"update_chunk": 4, "ref_advantage": "group", "ref_lr": 1e-3}),
    ("decentralized", {"chunk_rows": 256}),
    ("decentralized", {"safety_filter": True}),
    ("ic3net", {}),
    ("ic3net", {"baseline": "per_robot", "optimizer": "rmsprop"}),
    ("hierarchical", {"protocol": "mappo"}),
    ("hierarchical", {"protocol": "mappo", "local_credit": "credit", "ppo_epochs": 2}),
    ("decentralized", {"protocol": "mappo"}),
    ("ic3net", {"protocol": "mappo", "credit": "team"}),
]


def _env() -> EnvConfig:
    return EnvConfig.make(n_robots=6, layout="tiny", horizon=14, loss_p=0.3, groups=3, on_goal="stay")


def _build(method: str, params: dict[str, Any], device: Any = None, seed: int = 3) -> Any:
    extra = {} if device is None else {"device": device}
    return method_class(method)(_env(), {"batch_episodes": 2, "eval_chunk": 2, **params}, seed=seed, **extra)


def _fingerprint(m: Any, iterations: int = 2) -> str:
    """Training rows (no wall times), evaluation rows in three modes, and every module's
    and optimizer's state (on the host), as one string."""
    rows = [r for _ in range(iterations) for r in m.train_iteration()]
    for r in rows:
        r.pop("wall_s")
    evals = [r for mode in ("argmax", "sample", "sample@0.5") for r in m.evaluate(0, execution=mode)]
    return _with_state(m, [rows, evals])


def _with_state(m: Any, rows: Any) -> str:
    state = {k: v for k, v in m.state_dict().items() if k not in ("torch_gen", "torch_global")}
    flat: list[Any] = []

    def walk(x: Any) -> None:
        if isinstance(x, torch.Tensor):
            assert x.device.type == "cpu", "state_dict() holds a device tensor"
            flat.append(x.detach().double().flatten().tolist())
        elif isinstance(x, dict):
            for k in sorted(x, key=str):
                flat.append(str(k))
                walk(x[k])
        elif isinstance(x, list | tuple):
            for v in x:
                walk(v)
        else:
            flat.append(x)

    walk(state)
    return json.dumps([rows, flat], sort_keys=True, default=float)


def test_explicit_cpu_is_the_default_bit_for_bit() -> None:
    for method, params in (CASES[0], CASES[4], CASES[6]):
        assert _fingerprint(_build(method, params, "cpu")) == _fingerprint(_build(method, params))
    assert _build("ic3net", {}, torch.device("cpu")).device == torch.device("cpu")


@pytest.mark.parametrize(("method", "params"), CASES, ids=[f"{m}-{json.dumps(p)}" for m, p in CASES])
def test_device_run_is_the_cpu_run(method: str, params: dict[str, Any]) -> None:
    """Everything a device touches is on it (else fake_cuda raises), and the numbers are the CPU's."""
    want = _fingerprint(_build(method, params))
    with fake_cuda():
        m = _build(method, params, "cuda")
        assert all(t.device.type == "cuda" for mod in m.modules().values() if isinstance(mod, torch.nn.Module)
                   for t in [*mod.parameters(), *mod.buffers()])
        got = _fingerprint(m)
    assert got == want


def test_a_device_checkpoint_resumes_on_the_device_and_on_the_cpu() -> None:
    """state_dict() of a device run is on the host; loaded into a device method or a CPU one,
    training continues as the uninterrupted run."""
    method, params = "hierarchical", {"protocol": "mappo"}
    ref = _build(method, params)
    ref.train_iteration()
    want = _fingerprint(ref, 1)
    with fake_cuda():
        m = _build(method, params, "cuda")
        m.train_iteration()
        state = m.state_dict()
        again = _build(method, params, "cuda", seed=3)
        again.load_state_dict(copy.deepcopy(state))  # as a worker hands it over (no shared step counters)
        on_device = _fingerprint(again, 1)
    cpu = _build(method, params)
    cpu.load_state_dict(copy.deepcopy(state))
    assert on_device == want
    assert _fingerprint(cpu, 1) == want


def test_seed_stacked_training_on_the_device() -> None:
    params = {"batch_episodes": 2}
    alone = [_build("hierarchical", params, seed=s) for s in (0, 1)]
    want = [_with_state(m, [[{k: v for k, v in r.items() if k != "wall_s"} for r in m.train_iteration()]])
            for m in alone]
    with fake_cuda():
        stacked = [_build("hierarchical", params, "cuda", seed=s) for s in (0, 1)]
        rows = train_stacked(stacked)
        got = [_with_state(m, [[{k: v for k, v in r.items() if k != "wall_s"} for r in part]])
               for m, part in zip(stacked, rows, strict=True)]
    assert got == want


def test_fake_cuda_raises_where_cuda_would() -> None:
    """The helper itself: a host tensor into a device layer, a host generator sampling on
    the device, numpy() of a device tensor (else the tests above prove nothing)."""
    with fake_cuda():
        layer = torch.nn.Linear(3, 2).to("cuda")
        with pytest.raises(RuntimeError, match="same device"):
            layer(torch.ones(1, 3))
        x = layer(torch.ones(1, 3).to("cuda"))
        with pytest.raises(RuntimeError, match="generator"):
            torch.empty_like(x).exponential_(1, generator=torch.Generator())
        with pytest.raises(TypeError, match="numpy"):
            x.detach().numpy()
        assert x.device.type == "cuda" and x.cpu().device.type == "cpu"


@pytest.mark.parametrize(("name", "why"), [
    ("cudaa", "not a torch device"),
    ("gpu", "not a torch device"),
    ("meta", "holds no data"),
])
def test_a_bad_device_is_one_line(name: str, why: str) -> None:
    with pytest.raises(BenchError, match=why) as err:
        resolve_device(name, "--device")
    assert "\n" not in str(err.value) and str(err.value).startswith(f"--device {name!r}")


def test_cuda_without_a_cuda_device(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    with pytest.raises(BenchError, match="no CUDA device is available here"):
        check_device("cuda")
    with pytest.raises(BenchError, match="no CUDA device"):
        _build("decentralized", {}, "cuda")
    assert check_device(None) == "cpu" and check_device("cpu") == "cpu"


def test_a_missing_cuda_index() -> None:
    with fake_cuda():
        assert str(resolve_device("cuda:0")) == "cuda:0"
        with pytest.raises(BenchError, match="CUDA device 3 does not exist"):
            resolve_device("cuda:3")


def test_host_tree_moves_every_tensor() -> None:
    with fake_cuda():
        tree = {"a": torch.ones(2).to("cuda"), "b": [torch.zeros(1).to("cuda"), 3], "c": (torch.ones(()),)}
        out = host_tree(tree)
        assert out["a"].device.type == "cpu" and out["b"][0].device.type == "cpu" and out["b"][1] == 3
        assert isinstance(out["c"], tuple)
