"""examples/mappo_plugin: an outside method learns with the mappo protocol through its API."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest
import torch

from envs.config import EnvConfig

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "mappo_plugin"


def test_the_example_plugin_learns_with_mappo(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(EXAMPLE))
    from mappo_walker import MappoWalker  # type: ignore[import-not-found]

    env = EnvConfig.make(n_robots=6, layout="tiny", horizon=12, loss_p=0.3, groups=2, on_goal="stay")
    m = MappoWalker(env, {"batch_episodes": 2, "protocol": "mappo"}, seed=0)
    before = [q.detach().clone() for q in m.actor.parameters()]
    rows = [r for _ in range(2) for r in m.train_iteration()]
    assert len(rows) == 4 and all(r["critic_loss"] >= 0 and r["diag_kl"] >= 0 for r in rows)
    assert any(not torch.equal(a, b) for a, b in zip(before, m.actor.parameters(), strict=True))
    assert 0.0 <= m.evaluate(0, execution="sample")[0]["success_rate"] <= 1.0
    with pytest.raises(ValueError, match="mappo"):
        MappoWalker(env, {"batch_episodes": 2}, seed=0).train_iteration()
    sys.modules.pop("mappo_walker", None)
