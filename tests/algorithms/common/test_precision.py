"""``precision = "bf16"`` (algorithms/common/precision.py, decision 0241): the updates'
network forward passes under ``torch.autocast(bfloat16)``; the default ``"fp32"`` changes
nothing (scripts/train_hashes.py checks the bits against the code before the option).

Which dtype each matrix product ran in is observed with a dispatch mode (every aten op,
backward included, after autocast has chosen its dtype)."""
from __future__ import annotations

import copy
import json
from typing import Any

import pytest
import torch
from torch.overrides import TorchFunctionMode
from torch.utils._python_dispatch import TorchDispatchMode

from algorithms.common.precision import BF16, FP32, precision_of
from algorithms.common.seed_stack import train_stacked
from algorithms.registry import method_class
from bench.design.cells import Cell
from bench.execute.plan import params_changes
from envs.config import EnvConfig
from envs.errors import BenchError
from reports.data.variants import cell_variants

MATMULS = {"mm", "addmm", "bmm", "baddbmm", "linear", "matmul"}
CASES: list[tuple[str, dict[str, Any]]] = [
    ("hierarchical", {}),
    ("hierarchical", {"protocol": "mappo"}),
    ("decentralized", {}),
    ("decentralized", {"protocol": "mappo"}),
    ("ic3net", {}),
    ("ic3net", {"protocol": "mappo"}),
]
IDS = [f"{m}-{p.get('protocol', 'paper')}" for m, p in CASES]


class MatmulDtypes(TorchDispatchMode):
    """Records the dtypes of the first operand of every matrix product, and every dtype any op returned."""

    def __init__(self) -> None:
        super().__init__()
        self.matmuls: set[torch.dtype] = set()
        self.outputs: set[torch.dtype] = set()

    def __torch_dispatch__(self, func: Any, types: Any, args: Any = (), kwargs: Any = None) -> Any:
        out = func(*args, **(kwargs or {}))
        name = func.overloadpacket.__name__
        if name in MATMULS:
            self.matmuls.add(args[1].dtype if name in ("addmm", "baddbmm") else args[0].dtype)
        for t in out if isinstance(out, tuple | list) else (out,):
            if isinstance(t, torch.Tensor):
                self.outputs.add(t.dtype)
        return out


class Bf16OutsideAutocast(TorchFunctionMode):
    """Records the torch functions that returned a bf16 tensor outside an autocast region
    (forward only: backward runs below this mode): the losses' arithmetic, if anything."""

    def __init__(self) -> None:
        super().__init__()
        self.stray: set[str] = set()

    def __torch_function__(self, func: Any, types: Any, args: Any = (), kwargs: Any = None) -> Any:
        out = func(*args, **(kwargs or {}))
        if (isinstance(out, torch.Tensor) and out.dtype == torch.bfloat16
                and not torch.is_autocast_enabled("cpu")):
            self.stray.add(getattr(func, "__name__", str(func)))
        return out


def _env() -> EnvConfig:
    return EnvConfig.make(n_robots=6, layout="tiny", horizon=14, loss_p=0.3, groups=3, on_goal="stay")


def _build(method: str, params: dict[str, Any], seed: int = 3) -> Any:
    return method_class(method)(_env(), {"batch_episodes": 2, "eval_chunk": 2, **params}, seed=seed)


def _train(m: Any, iterations: int = 2) -> list[dict[str, Any]]:
    rows = [r for _ in range(iterations) for r in m.train_iteration()]
    for r in rows:
        r.pop("wall_s")
    return rows


def _state(m: Any) -> dict[str, Any]:
    return {k: v for k, v in m.state_dict().items() if k not in ("torch_gen", "torch_global")}


def _flat(tree: Any) -> list[float]:
    if isinstance(tree, torch.Tensor):
        return tree.detach().double().flatten().tolist()
    if isinstance(tree, dict):
        return [x for k in sorted(tree, key=str) for x in _flat(tree[k])]
    if isinstance(tree, list | tuple):
        return [x for v in tree for x in _flat(v)]
    return [float(tree)] if isinstance(tree, int | float) and not isinstance(tree, bool) else []


def _tensors(tree: Any) -> list[torch.Tensor]:
    if isinstance(tree, torch.Tensor):
        return [tree]
    if isinstance(tree, dict):
        return [t for v in tree.values() for t in _tensors(v)]
    if isinstance(tree, list | tuple):
        return [t for v in tree for t in _tensors(v)]
    return []


@pytest.mark.parametrize(("method", "params"), CASES, ids=IDS)
def test_fp32__runs_no_op_in_bf16_and_equals_the_default(method: str, params: dict[str, Any]) -> None:
    """The default enters no autocast region: not one bf16 tensor anywhere in training, and
    an explicit ``precision = "fp32"`` is the default bit for bit."""
    m = _build(method, params)
    assert all(precision_of(mod) == FP32 for mod in m.modules().values())
    with MatmulDtypes() as seen:
        rows = _train(m)
    assert torch.bfloat16 not in seen.outputs and seen.matmuls == {torch.float32}
    explicit = _build(method, {**params, "precision": "fp32"})
    assert json.dumps(_train(explicit), sort_keys=True) == json.dumps(rows, sort_keys=True)
    assert _flat(_state(explicit)) == _flat(_state(m))


@pytest.mark.parametrize(("method", "params"), CASES, ids=IDS)
def test_bf16__the_update_multiplies_in_bf16_and_keeps_parameters_and_losses_fp32(
        method: str, params: dict[str, Any]) -> None:
    ref = _build(method, params)
    m = _build(method, {**params, "precision": "bf16"})
    assert all(precision_of(mod) == BF16 for mod in m.modules().values())
    with MatmulDtypes() as seen, Bf16OutsideAutocast() as outside:
        rows = _train(m)
    assert torch.bfloat16 in seen.matmuls  # autocast ran products in bf16
    assert not outside.stray, f"bf16 tensors outside autocast (the losses must be float32): {outside.stray}"
    want = _train(ref)
    # Parameters, optimizer states and buffers keep the fp32 run's dtypes (autocast semantics).
    assert [t.dtype for t in _tensors(_state(m))] == [t.dtype for t in _tensors(_state(ref))]
    assert torch.bfloat16 not in {t.dtype for t in _tensors(_state(m))}
    for key in ("critic_loss", "actor_loss"):
        got, exp = [r[key] for r in rows], [r[key] for r in want]
        assert got != exp, f"{key}: bf16 gave the fp32 numbers"  # it changes the numbers ...
        assert got == pytest.approx(exp, rel=0.05, abs=0.05)  # ... by rounding, not by a different loss
    assert all(isinstance(r[k], float) for r in rows for k in ("critic_loss", "actor_loss"))


@pytest.mark.parametrize(("method", "params"), [CASES[0], CASES[2], CASES[4]], ids=[IDS[0], IDS[2], IDS[4]])
def test_bf16__rollouts_and_evaluation_stay_fp32(method: str, params: dict[str, Any]) -> None:
    """Where it does not pay (decision 0241) autocast is off: evaluation and the rollout
    multiply in float32, so a bf16 cell evaluates its weights exactly as an fp32 cell would."""
    m = _build(method, {**params, "precision": "bf16"})
    twin = _build(method, params)
    _train(m, 1)
    twin.load_state_dict(copy.deepcopy(m.state_dict()))
    with MatmulDtypes() as seen:
        got = m.evaluate(0, execution="sample")
    assert seen.matmuls == {torch.float32}
    assert json.dumps(got) == json.dumps(twin.evaluate(0, execution="sample"))  # NaN-safe


def test_bf16__a_checkpoint_resumes_exactly() -> None:
    """The precision comes from the parameters, not the state: a bf16 method resumed from its
    checkpoint continues as the uninterrupted run."""
    params = {"precision": "bf16"}
    whole = _build("hierarchical", params)
    first = _train(whole, 1)
    state = copy.deepcopy(whole.state_dict())
    want = _train(whole, 1)
    again = _build("hierarchical", params)
    again.load_state_dict(state)
    assert first and json.dumps(_train(again, 1)) == json.dumps(want)  # NaN-safe


@pytest.mark.parametrize("method", ["hierarchical", "decentralized"])
def test_bf16__seed_stacked_cells_equal_single_cells(method: str) -> None:
    """The stacked training (``bench run --stack-seeds``) calls each seed's update itself: the
    tag on its networks gives it bf16 there too, and each seed's rows stay its own run's."""
    params = {"precision": "bf16"}
    alone = [_build(method, params, seed=s) for s in (3, 4)]
    want = [_train(m, 1) for m in alone]
    stacked = [_build(method, params, seed=s) for s in (3, 4)]
    got = train_stacked(stacked)
    for rows in got:
        for r in rows:
            r.pop("wall_s")
    assert json.dumps(got) == json.dumps(want)
    assert [_flat(_state(m)) for m in stacked] == [_flat(_state(m)) for m in alone]


def _cell(**extra: Any) -> Cell:
    return Cell.make(method="decentralized", n_robots=8, loss_p=0.2, layout="tiny", **extra)


def test_params__default_cells_keep_their_ids_and_bf16_cells_say_so() -> None:
    default, bf16 = _cell(), _cell(params={"precision": "bf16"})
    assert "precision" not in default.canonical_json()  # every existing cell id stays
    assert _cell(params={}).cell_id == default.cell_id != bf16.cell_id
    assert json.loads(bf16.config_columns()["params_json"])["precision"] == "bf16"
    assert type(bf16.method_params())(**json.loads(bf16.config_columns()["params_json"])) == bf16.method_params()
    # A cell stored before the parameter existed is no change at the default (decision 0216)
    stored = default.method_params().model_dump(mode="json")
    del stored["precision"]
    assert params_changes(json.dumps(stored), default) == []
    assert params_changes(json.dumps(stored), bf16) == ['precision: (absent) -> "bf16"']


def test_params__a_bad_precision_is_one_line_naming_it() -> None:
    with pytest.raises(BenchError) as exc:
        _cell(params={"precision": "fp16"})
    msg = str(exc.value)
    assert "\n" not in msg and "precision" in msg and "'fp32' or 'bf16'" in msg
    with pytest.raises(BenchError, match="precision"):
        method_class("ic3net").parse_params({"precision": "bfloat16"})


def test_reports__a_bf16_cell_is_a_variant_of_its_method() -> None:
    """The reports never pool bf16 cells with fp32 ones: beside fp32 cells (stored with or
    without the parameter) a bf16 cell is labelled ``precision=bf16``; Table I, the figures
    and the claims use the default variant only (reports/data/variants.py)."""
    rows = []
    for seed, extra in ((0, {}), (1, {}), (2, {"params": {"precision": "bf16"}})):
        cols = _cell(seed=seed, **extra).config_columns()
        if seed == 0:  # a row stored before the parameter existed
            params = json.loads(cols["params_json"])
            del params["precision"]
            cols["params_json"] = json.dumps(params)
        rows.append({**cols, "task": "one-shot"})
    import pandas as pd

    labels = cell_variants(pd.DataFrame(rows)).tolist()
    assert labels == ["", "", "precision=bf16"]



def test_ppo_actor_update__a_bf16_policy_s_log_probs_come_back_float32() -> None:
    """A policy whose log-probabilities autocast leaves in bf16 (a plain linear head, as a
    plugin may have; the built-ins' action paths add float32 terms): the surrogate, its
    normalization and the entropy bonus are still float32 (ppo.py casts them back)."""
    from algorithms.common.ppo import PPOBatch, ppo_actor_update
    from algorithms.common.precision import tag

    torch.manual_seed(0)
    policy = torch.nn.Linear(4, 5)
    opt = torch.optim.Adam(policy.parameters(), lr=1e-3)
    tag([policy, opt], "bf16")
    x, actions = torch.randn(64, 4), torch.randint(0, 5, (64,))

    def log_probs(ix: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        logp_all = torch.log_softmax(policy(x[ix]), dim=-1)
        logp = logp_all.gather(-1, actions[ix, None])
        return logp, -(logp_all.exp() * logp_all).sum(-1, keepdim=True), torch.ones_like(logp)

    with MatmulDtypes() as seen, Bf16OutsideAutocast() as outside:
        out = ppo_actor_update(PPOBatch(64, log_probs, torch.randn(64, 1)), opt, 2, 2, 0.2, 0.01, 10.0,
                               torch.Generator().manual_seed(1))
    assert torch.bfloat16 in seen.matmuls and not outside.stray
    assert all(p.dtype == torch.float32 and p.grad is not None and p.grad.dtype == torch.float32
               for p in policy.parameters())
    assert all(v == v for v in out.values())  # finite, no NaN
