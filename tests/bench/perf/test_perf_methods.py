"""bench/perf/methods.py on a toy configuration (shape of the results, not speed).

Runtime: about 2 s.
"""
from __future__ import annotations

import math

from bench.perf.methods import (
    measure_cell_training,
    measure_filter,
    measure_training,
    run_train_suite,
)


def test_measure_training__reports_throughput_and_projection() -> None:
    row = measure_training("hierarchical", 8, "tiny", iterations=1, batch_episodes=2, horizon=12)
    assert row["episode_steps"] > 0
    assert row["env_steps_per_s"] > 0 and math.isclose(row["agent_steps_per_s"], 8 * row["env_steps_per_s"])
    assert row["paper_cell_train_min"] > 0


def test_measure_filter__counts_group_steps_and_candidates() -> None:
    row = measure_filter(8, "tiny", horizon=12, batch_episodes=2)
    assert 0 < row["group_steps"] <= 2 * 12 * 4
    assert row["mean_candidates"] >= 1.0
    assert 0.0 <= row["fallback_rate"] <= 1.0 and 0.0 <= row["correction_rate"] <= 1.0
    assert row["filter_us_per_group_step"] > 0


def test_measure_cell_training__times_whole_updates_in_wall_and_cpu() -> None:
    row = measure_cell_training("decentralized", 6, "tiny", iterations=2, warmup=1, batch_episodes=2, horizon=10)
    assert 0 < row["episode_steps"] <= 2 * 2 * 10
    assert row["env_steps_per_s"] > 0 and row["env_steps_per_s_cpu"] > 0
    assert math.isclose(row["agent_steps_per_s_cpu"], 6 * row["env_steps_per_s_cpu"])


def test_run_train_suite__one_row_per_method_and_size_and_the_stacked_rows() -> None:
    df = run_train_suite(iterations=1, horizon=6, batch_episodes=1, sizes=(4, 6), layout="tiny")
    assert sorted(zip(df["method"], df["n_robots"], df["stacked_seeds"], strict=True)) == sorted(
        [(m, n, 1) for m in ("hierarchical", "decentralized", "ic3net") for n in (4, 6)]
        + [(m, n, 3) for m in ("hierarchical", "decentralized", "ic3net") for n in (4, 6)])
    assert (df["suite"] == "train").all() and (df["env_steps_per_s"] > 0).all()
    stacked = df[df["stacked_seeds"] == 3]
    assert (stacked["episode_steps"] == 3 * 6).all()  # three seeds x one episode x horizon 6
