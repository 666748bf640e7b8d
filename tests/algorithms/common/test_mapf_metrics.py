"""CSR, sum of costs, makespan and throughput of EpisodeStats rows, as POGEMA defines them
(docs/decisions/0212), against hand-counted episodes; older eval files read them as NaN."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from algorithms.common.episodes import MAPF_METRICS, Decision, EpisodeStats
from bench.store.run_store import read_table
from bench.store.schema import EVAL_SCHEMA, rows_to_table, with_version


def _run(reached_at: list[list[int | None]], ends: list[int], lifelong: bool = False,
         extra_goals: set[tuple[int, int]] | None = None) -> list[dict]:
    """Episodes whose robot i first reaches its goal at step reached_at[b][i] (1-based; 0:
    on its goal at the start; None: never) and that end after ends[b] steps."""
    b, n = len(reached_at), len(reached_at[0])
    stats = EpisodeStats(b, n, lifelong=lifelong)
    done = np.array([[r == 0 for r in row] for row in reached_at])
    for t in range(1, max(ends) + 1):
        running = np.array([t <= e for e in ends])
        reached = np.array([[r == t for r in row] for row in reached_at]) & running[:, None]
        for eb, step in sorted(extra_goals or set()):  # lifelong: later goals of robot 0
            if step == t:
                reached[eb, 0] = True
        done |= reached
        zeros = np.zeros((b, n))
        res = SimpleNamespace(reward=np.zeros(b), collision=zeros.astype(bool), active=~done & running[:, None],
                              invalid=zeros.astype(bool), reached=reached)
        stats.add(running, res, Decision(actions=np.zeros((b, n), dtype=np.int64)))
    return stats.finish(done)


def test_one_shot__csr_sum_of_costs_makespan():
    rows = _run([[2, 4, 5], [0, 1, None]], ends=[5, 7])
    assert [r["csr"] for r in rows] == [1.0, 0.0]
    assert rows[0]["sum_of_costs"] == 2 + 4 + 5 and rows[0]["makespan"] == 5
    assert rows[1]["sum_of_costs"] == 0 + 1 + 7 and rows[1]["makespan"] == 7  # never: the episode's length
    assert all(math.isnan(r["throughput"]) for r in rows)


def test_lifelong__throughput_is_goals_per_step():
    rows = _run([[3, None], [None, None]], ends=[10, 10], lifelong=True, extra_goals={(0, 6), (0, 9)})
    assert rows[0]["throughput"] == 3 / 10 and rows[1]["throughput"] == 0.0
    assert all(math.isnan(r[k]) for r in rows for k in ("csr", "sum_of_costs", "makespan"))


def test_an_eval_file_older_than_the_metrics_reads_them_as_nan(tmp_path):
    row = {"cell_id": "c", "episode": 0, "execution": "planner", "scenario": "s", "steps": 3, "csr": 1.0}
    table = rows_to_table([row], EVAL_SCHEMA)
    old = table.drop_columns(list(MAPF_METRICS))
    pq.write_table(old.replace_schema_metadata(with_version(old.schema).metadata), tmp_path / "e.parquet")
    got = read_table(tmp_path / "e.parquet", EVAL_SCHEMA).select(EVAL_SCHEMA.names).cast(EVAL_SCHEMA)
    assert got.schema.names == EVAL_SCHEMA.names
    assert all(math.isnan(got.column(k)[0].as_py()) for k in MAPF_METRICS)
    assert table.column("csr")[0].as_py() == 1.0 and isinstance(table, pa.Table)
