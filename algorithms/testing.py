"""The Method contract as a test suite any package can run against its own method.

The built-in methods pass it (tests/algorithms/test_method_contract.py), and so does the
worked outside package in examples/external_method/. In your package's tests::

    from algorithms.testing import MethodContract

    class TestMyMethod(MethodContract):
        method = "mypkg.greedy:GreedyMethod"   # or the name your entry point registers

and run ``pytest``. Each test states one rule of the contract (docs/extending.md): traits
the harness reads are declared and valid; ``decide`` gives an integer action in 0..4 for
every robot; evaluation rows carry every metric in range, with the same scenarios in every
execution mode; a learned method's update changes its parameters with finite losses, a
planner learns nothing; the same seed gives the same rows, and evaluation chunks do not
consume the training streams (any worker split gives the same rows); an observer passed to
``evaluate`` sees one ``StepRecord`` per step with the documented shapes and changes no
number; a checkpoint saved
with ``torch.save`` and loaded with ``torch.load(weights_only=True)`` continues exactly.
Mirrors Optuna's shared storage tests (``optuna.testing``). About 5-20 s per method.
"""
from __future__ import annotations

import io
import math
import re
from typing import Any, ClassVar

import numpy as np
import pandas as pd
import pytest
import torch

from algorithms.base import BASELINE, REFERENCE, Method, MethodParams
from algorithms.common.episodes import EVAL_METRICS, EpisodeBatch, batch_rng
from algorithms.common.execution import ActionChoice
from algorithms.common.observer import StepRecord
from algorithms.registry import method_class
from envs.config import EnvConfig

__all__ = ["MethodContract"]

_HEX = re.compile(r"^#[0-9a-fA-F]{6}$")


def rows_frame(rows: list[dict[str, Any]]) -> pd.DataFrame:
    """Rows as a frame without their wall times (which differ between runs)."""
    return pd.DataFrame(rows).drop(columns=["wall_s"], errors="ignore")


def parameters(method: Method) -> list[torch.Tensor]:
    """Copies of every parameter of the method's checkpointed networks."""
    return [p.detach().clone() for mod in method.modules().values()
            if isinstance(mod, torch.nn.Module) for p in mod.parameters()]


class MethodContract:
    """Subclass as ``TestX`` and set ``method`` (a registered name or ``module:Class``);
    override ``env`` or ``params`` for a method that needs other sizes (keep them small:
    every test builds the method afresh)."""

    method: ClassVar[str] = ""
    env: ClassVar[EnvConfig] = EnvConfig(n_robots=6, layout="tiny", horizon=12, groups=2, loss_p=0.3)
    params: ClassVar[dict[str, Any]] = {"batch_episodes": 2, "eval_chunk": 2}

    @pytest.fixture
    def method_spec(self) -> str:
        """The method under test (a subclass may parametrize this fixture instead)."""
        assert self.method, "set `method` to a registered name or module:Class"
        return self.method

    def make(self, spec: str, seed: int = 3) -> Method:
        return method_class(spec)(self.env, self.params, seed=seed)

    def test_declares_the_traits_the_harness_reads(self, method_spec: str) -> None:
        cls = method_class(method_spec)
        assert isinstance(cls.name, str) and cls.name, "a method has a non-empty `name`"
        assert isinstance(cls.learned, bool)
        assert isinstance(cls.safety_filter_default, bool)
        assert isinstance(cls.label(), str) and cls.label()
        assert _HEX.match(cls.color), f"color must be '#rrggbb', got {cls.color!r}"
        assert isinstance(cls.payload_model, str) and cls.payload_model
        assert issubclass(cls.Params, MethodParams)
        assert cls.paper_role in (REFERENCE, BASELINE, ""), \
            f"paper_role must be REFERENCE, BASELINE or '', got {cls.paper_role!r}"
        modes = cls.execution_modes()
        assert modes and (modes == ("planner",)) == (not cls.learned)

    @pytest.mark.parametrize("mode", ["train", "argmax", "sample@0.5"])
    def test_decide_gives_valid_actions_for_every_robot(self, method_spec: str, mode: str) -> None:
        m = self.make(method_spec)
        if mode == "train" and not m.learned:
            pytest.skip("a planner does not train")
        batch = EpisodeBatch(self.env, 3, batch_rng(0, 1, 0), m.layout)
        choice = (ActionChoice.train(m.torch_gen) if mode == "train"
                  else m.execution_choice(mode if m.learned else None, 0, 0))
        with torch.no_grad():
            state = m.begin(batch, choice)
            for _ in range(3):
                dec = m.decide(batch, state, choice)
                assert dec.actions.shape == (3, self.env.n_robots)
                assert np.issubdtype(dec.actions.dtype, np.integer)
                assert dec.actions.min() >= 0 and dec.actions.max() <= 4
                res = batch.core.step(dec.actions)
                m.observe(batch, state, res)

    def test_evaluation_rows_hold_every_metric_in_range(self, method_spec: str) -> None:
        rows = self.make(method_spec).evaluate(0)
        assert len(rows) == self.params["eval_chunk"]
        for row in rows:
            assert set(EVAL_METRICS) <= set(row)
            for key in ("success_rate", "collision_rate", "invalid_rate", "correction_rate"):
                assert 0.0 <= row[key] <= 1.0, key
            assert 1 <= row["steps"] <= self.env.horizon
            assert math.isfinite(row["team_return"])
            payload = row["payload_scalars_per_step"]  # NaN: the method does not communicate
            assert math.isnan(payload) or payload >= 0
            for key in ("mean_candidates", "fallback_rate", "predictor_error"):  # NaN: not used
                assert math.isnan(row[key]) or row[key] >= 0, key
            assert row["payload_dec_per_step"] == self.env.n_robots * (self.env.n_robots - 1) * self.env.d_m

    def test_every_execution_mode_sees_the_same_scenarios(self, method_spec: str) -> None:
        m = self.make(method_spec)
        seen = {mode: [r["scenario"] for r in m.evaluate(0, execution=mode)] for mode in m.execution_modes()}
        first = next(iter(seen.values()))
        assert all(s == first for s in seen.values()), seen
        assert len(set(first)) == len(first), "episodes of one chunk have distinct scenarios"

    def test_training_update_changes_parameters_with_finite_losses(self, method_spec: str) -> None:
        m = self.make(method_spec)
        if not m.learned:
            assert m.train_iteration() == []
            return
        before = parameters(m)
        assert before, "a learned method must expose its networks through modules()"
        rows = m.train_iteration()
        assert len(rows) == self.params["batch_episodes"]
        after = parameters(m)
        assert any(not torch.equal(a, b) for a, b in zip(before, after, strict=True))
        losses = {k: v for k, v in rows[0].items() if "loss" in k}
        assert losses, "training rows must carry the losses"
        assert all(math.isfinite(v) for v in losses.values()), losses
        assert m.iterations == 1 and m.episodes_done == self.params["batch_episodes"]

    def test_same_seed_gives_same_metrics(self, method_spec: str) -> None:
        a, b = self.make(method_spec, seed=5), self.make(method_spec, seed=5)
        pd.testing.assert_frame_equal(rows_frame(a.train_iteration()), rows_frame(b.train_iteration()))
        pd.testing.assert_frame_equal(pd.DataFrame(a.evaluate(1)), pd.DataFrame(b.evaluate(1)))
        # Evaluation chunks do not consume the training streams: any worker split gives these rows.
        b.evaluate(0)
        pd.testing.assert_frame_equal(pd.DataFrame(a.evaluate(1)), pd.DataFrame(b.evaluate(1)))
        pd.testing.assert_frame_equal(rows_frame(a.train_iteration()), rows_frame(b.train_iteration()))

    def test_checkpoint_round_trip_continues_identically(self, method_spec: str) -> None:
        m = self.make(method_spec, seed=7)
        m.train_iteration()
        buf = io.BytesIO()
        torch.save(m.state_dict(), buf)
        buf.seek(0)
        restored = self.make(method_spec, seed=7)
        restored.load_state_dict(torch.load(buf, weights_only=True))
        pd.testing.assert_frame_equal(pd.DataFrame(m.evaluate(0)), pd.DataFrame(restored.evaluate(0)))
        pd.testing.assert_frame_equal(rows_frame(m.train_iteration()),
                                      rows_frame(restored.train_iteration()))
        for x, y in zip(parameters(m), parameters(restored), strict=True):
            assert torch.equal(x, y)

    def test_an_observer_sees_every_step_and_changes_no_number(self, method_spec: str) -> None:
        seen: list[StepRecord] = []
        observed, plain = self.make(method_spec), self.make(method_spec)
        rows = observed.evaluate(0, observer=seen.append)
        pd.testing.assert_frame_equal(pd.DataFrame(rows), pd.DataFrame(plain.evaluate(0)))
        b, n, z = self.params["eval_chunk"], self.env.n_robots, self.env.groups
        assert [r.t for r in seen] == list(range(len(seen))), "one record per step, in order"
        for k, row in enumerate(rows):  # each episode is seen on each of its steps
            assert sum(int(r.running[k]) for r in seen) == row["steps"]
        for r in seen:
            assert r.running.shape == (b,) and r.fallbacks.shape == r.candidates.shape == (b,)
            for a in (r.goal, r.before.pos, r.before.done, r.before.on_floor, r.after.pos, r.after.done,
                      r.after.on_floor, r.proposed, r.actions, r.corrected):
                assert a.shape == (b, n)
            assert r.actions.min() >= 0 and r.actions.max() <= 4
            assert r.group_links.dtype == bool and r.group_links.shape in ((b, 0, 0), (b, z, z))
            assert r.robot_links.dtype == bool and r.robot_links.shape in ((b, 0, 0), (b, n, n))
            if not r.has_proposals:
                assert np.array_equal(r.proposed, r.actions) and not r.corrected.any()
            assert not (r.corrected & ~r.result.active).any(), "only active robots are corrected"
        # Observing draws from no stream: what follows is unchanged too.
        pd.testing.assert_frame_equal(rows_frame(observed.train_iteration()), rows_frame(plain.train_iteration()))
