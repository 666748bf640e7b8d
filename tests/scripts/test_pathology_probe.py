"""scripts/pathology_probe.py: each fallback rule is evaluated on the same weights, the
paper's joint Wait is the method's own argmax evaluation, and the method is left as it was."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from algorithms.hierarchical.method import HierarchicalMethod
from envs.config import EnvConfig

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"
sys.path.insert(0, str(SCRIPTS))  # the script imports scripts/reference_probe.py by name
_spec = importlib.util.spec_from_file_location("pathology_probe", SCRIPTS / "pathology_probe.py")
probe = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(probe)


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_fallback_table_swaps_only_the_rule_and_restores_the_method() -> None:
    env = EnvConfig.make(n_robots=8, layout="tiny", horizon=24, loss_p=0.3, groups=2)
    m = HierarchicalMethod(env, {"batch_episodes": 2, "eval_chunk": 4}, seed=1)
    m.train_iteration()
    before = m.params
    table = probe.fallback_table(m, chunks=1)
    assert m.params is before
    assert set(table) == {"argmax/joint", "sample/joint", "argmax/resample", "argmax/per_robot",
                          "argmax/per_robot+resample"}
    rows = m.evaluate(0, seed=probe.EVAL_SEED, execution="argmax")
    assert table["argmax/joint"]["fallback_rate"] == pytest.approx(np.mean([r["fallback_rate"] for r in rows]))
    assert table["argmax/joint"]["success_rate"] == pytest.approx(np.mean([r["success_rate"] for r in rows]))
    # the rule does act: resampling at argmax changes what the filter sees
    assert table["argmax/resample"] != table["argmax/joint"]


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_checkpoint_is_probed_at_its_cells_configuration_with_its_weights(tmp_path: Path) -> None:
    from bench.design.cells import Cell
    from bench.store.run_store import RunStore

    cell = Cell.make(method="hierarchical", n_robots=8, loss_p=0.3, layout="tiny", horizon=24, groups=2, seed=5,
                     episodes=2, params={"batch_episodes": 2, "eval_chunk": 4, "fallback": "per_robot"})
    trained = HierarchicalMethod(cell.to_env_config(), cell.method_params().model_dump(mode="json"), seed=5)
    trained.train_iteration()
    store = RunStore(tmp_path / "run")
    store.write_checkpoint(cell.cell_id, {"cell": cell.canonical_json(), "method": "hierarchical",
                                          "episodes_done": 2, "state": trained.state_dict()})
    m, rec = probe._from_checkpoint("x", str(store.ckpt_path(cell.cell_id, "hierarchical")))
    assert (rec["n"], rec["p"], rec["horizon"], rec["seed"], rec["episodes"]) == (8, 0.3, 24, 5, 2)
    assert m.params == trained.params and m.params.fallback == "per_robot"
    want = pd.DataFrame(trained.evaluate(0, seed=probe.EVAL_SEED, execution="argmax"))
    got = pd.DataFrame(m.evaluate(0, seed=probe.EVAL_SEED, execution="argmax"))
    pd.testing.assert_frame_equal(got, want)  # the checkpoint's weights, bit for bit (NaN throughput alike)
