"""The per-update training diagnostics: every learned method reports them, they
measure what they say, and a train file written before them still reads."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import torch

from algorithms.common.diagnostic_columns import DIAGNOSTIC_COLUMNS
from algorithms.common.diagnostics import KLProbe, probe_rows, value_diagnostics, wait_share
from algorithms.registry import method_class
from bench.store.run_store import RunStore
from bench.store.schema import TRAIN_SCHEMA, with_version
from envs.actions import WAIT
from envs.config import EnvConfig

TWO_LEVELS = {"diag_entropy_ref", "diag_kl_ref"}


@pytest.mark.parametrize("method,params", [("decentralized", {}), ("ic3net", {}), ("hierarchical", {}),
                                           ("ic3net", {"baseline": "per_robot"})])
def test_every_learned_method_reports_its_diagnostics(method: str, params: dict) -> None:
    env = EnvConfig.make(n_robots=6, layout="tiny", horizon=12, loss_p=0.3, groups=2, on_goal="stay")
    m = method_class(method)(env, {"batch_episodes": 2, **params}, seed=1)
    rows = m.train_iteration()
    got = {k: rows[0][k] for k in DIAGNOSTIC_COLUMNS if k in rows[0]}
    expected = set(DIAGNOSTIC_COLUMNS) - (set() if method == "hierarchical" else TWO_LEVELS)
    if params.get("baseline") == "per_robot":
        expected.discard("diag_critic_grad_norm")  # no central critic
    assert set(got) == expected
    assert all(math.isfinite(v) for v in got.values()), got
    assert 0.0 <= got["diag_wait_share"] <= 1.0 and got["diag_entropy"] > 0.0 and got["diag_kl"] >= 0.0
    assert got["diag_grad_norm"] == rows[0].get("grad_norm", got["diag_grad_norm"])


def test_value_diagnostics__explained_variance_and_raw_advantage() -> None:
    g = torch.tensor([[1.0, 2.0], [3.0, 5.0]])
    mask = torch.tensor([[1.0, 1.0], [1.0, 0.0]])  # the 5 is after the episode ended
    perfect = value_diagnostics(g, g, mask)
    assert perfect["diag_explained_variance"] == pytest.approx(1.0) and perfect["diag_adv_std"] == 0.0
    zero = value_diagnostics(torch.zeros_like(g), g, mask)
    assert zero["diag_explained_variance"] == pytest.approx(0.0)
    assert zero["diag_adv_mean"] == pytest.approx(2.0) and zero["diag_return_mean"] == pytest.approx(2.0)
    assert zero["diag_return_std"] == pytest.approx(np.std([1.0, 2.0, 3.0]))


def test_kl_probe__zero_without_a_change_and_the_categorical_kl_after_one() -> None:
    logits = torch.tensor([[0.0, 1.0, -1e9], [2.0, 0.0, 0.0]])
    box = {"x": logits.clone()}
    probe = KLProbe(lambda: (torch.log_softmax(box["x"], -1), None))
    assert probe.kl() == pytest.approx(0.0)
    box["x"] = logits + torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    p_old = torch.softmax(logits[0, :2], -1)
    p_new = torch.softmax(box["x"][0, :2], -1)
    want = float((p_old * (p_old.log() - p_new.log())).sum()) / 2  # the second row is unchanged
    assert probe.kl() == pytest.approx(want, rel=1e-5)


def test_wait_share_and_probe_rows() -> None:
    actions = np.array([[WAIT, 1], [WAIT, WAIT]])
    assert wait_share(actions, np.array([[True, True], [False, True]])) == pytest.approx(2 / 3)
    assert len(probe_rows(10)) == 10 and len(probe_rows(10_000, 100)) == 100
    assert probe_rows(10_000, 100)[-1] == 9_999


def test_a_train_file_without_the_diagnostics_reads_them_as_nan(tmp_path: Path) -> None:
    old = pa.schema([f for f in TRAIN_SCHEMA if f.name not in DIAGNOSTIC_COLUMNS])
    row = {f.name: ([0] if pa.types.is_integer(f.type) else [0.5] if pa.types.is_floating(f.type) else ["c"])
           for f in old}
    store = RunStore(tmp_path)
    part = store.train_dir / "c" / "000000.parquet"
    part.parent.mkdir(parents=True)
    pq.write_table(pa.Table.from_pydict(row, schema=with_version(old)), part)
    df = store.read_train()
    assert list(df.columns) == TRAIN_SCHEMA.names
    assert df[list(DIAGNOSTIC_COLUMNS)].isna().all().all() and df["actor_loss"].tolist() == [0.5]
