"""bench perf --suite peers: TorchRL's MAPPO (the README recipe) and our decentralized
trainer on the same environment and batch, and their ratio (structure only, no timing asserted)."""
from __future__ import annotations

import math

import pytest

from bench.perf.peers import run_peers_suite


@pytest.mark.slow
def test_run_peers_suite__torchrl_and_ours_at_each_n_with_their_ratio() -> None:
    df = run_peers_suite(sizes=(4,), frames=40, horizon=10, layout="tiny")
    peer = df[df["peer"] == "torchrl-mappo"].iloc[0]
    ours = df[df["peer"] == "ours-decentralized"].iloc[0]
    assert peer["env_steps"] == 40 and ours["env_steps"] <= 40 and ours["horizon"] == peer["horizon"] == 10
    assert math.isclose(peer["ratio_ours_over_torchrl"], ours["env_steps_per_s"] / peer["env_steps_per_s"])
    assert math.isclose(ours["ratio_ours_over_torchrl_cpu"], ours["env_steps_per_s_cpu"] / peer["env_steps_per_s_cpu"])
    assert "not measured" in df[df["peer"] == "benchmarl/epymarl"]["note"].iloc[0]
