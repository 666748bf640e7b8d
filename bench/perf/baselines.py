"""Training throughput of the learned baselines (decentralized, IC3Net) at N = 20 and 100.

``run_baselines_suite`` trains each baseline for ``iterations`` updates of
``batch_episodes`` episodes (horizon 500, the paper's, on the preset sized for N; an
untrained policy rarely finishes early, so episodes run close to the full horizon) and
times the rollout (decide + core step, no_grad) and the update separately
(``bench.perf.timing.time_training``). Columns are those of
``bench.perf.methods.measure_training``: ``env_steps_per_s`` (episode-steps of training
per second, rollout and update), ``agent_steps_per_s`` (x N), ``rollout_ms_per_step`` /
``update_ms_per_step`` (per batched step of B episodes), ``paper_cell_train_min`` (one
paper cell's training, 2000 episodes of 500 steps, from wall time) and
``paper_cell_train_min_cpu`` (from process CPU time: one dedicated core on a shared
machine); plus ``paper_cell_eval_min``, the projected time of its 100 evaluation
episodes (rollout only, sampled actions, no storage).

    .venv/bin/python -m bench.perf.baselines          # prints the table
"""
from __future__ import annotations

import pandas as pd

from bench.perf import budget
from bench.perf.methods import measure_training
from envs.layouts import preset_for

BASELINES = ("decentralized", "ic3net")


def run_baselines_suite(sizes: tuple[int, ...] = (20, 100), iterations: int = 1,
                        horizon: int = budget.HORIZON, batch_episodes: int = 8,
                        layout: str | None = None) -> pd.DataFrame:
    """One row per (baseline, N): training throughput and projected paper-cell times.

    ``layout`` None uses the preset sized for each N; the projections always assume the
    paper's 2000 x 500 training and 100 x 500 evaluation episode-steps.
    """
    rows = []
    for name in BASELINES:
        for n in sizes:
            row = measure_training(name, n, layout or preset_for(n), iterations=iterations,
                                   batch_episodes=batch_episodes, horizon=horizon)
            # Evaluation is a rollout without storage: B episodes per batched step.
            per_episode_step_s = row["rollout_ms_per_step"] / 1e3 / row["batch_episodes"]
            row["paper_cell_eval_min"] = per_episode_step_s * budget.EVAL_EPISODES * budget.HORIZON / 60
            rows.append({"suite": "baselines", **row})
    return pd.DataFrame(rows)


if __name__ == "__main__":
    print(run_baselines_suite().to_string(index=False))
