"""bench/perf/baselines.py on a toy configuration (shape of the results, not speed).

Runtime: about 3 s.
"""
from __future__ import annotations

import math

from bench.perf.baselines import run_baselines_suite


def test_run_baselines_suite__one_row_per_baseline_and_size_with_projections() -> None:
    df = run_baselines_suite(sizes=(4, 6), horizon=10, batch_episodes=2, layout="tiny")
    assert sorted(zip(df.method, df.n_robots, strict=True)) == [
        ("decentralized", 4), ("decentralized", 6), ("ic3net", 4), ("ic3net", 6)]
    assert (df.suite == "baselines").all()
    assert ((df.episode_steps > 0) & (df.episode_steps <= 2 * 10)).all()
    for row in df.itertuples():
        assert math.isclose(row.agent_steps_per_s, row.n_robots * row.env_steps_per_s)
        assert row.paper_cell_train_min > 0 and row.paper_cell_eval_min > 0
