"""The paper's experimental settings, each stated once (Sec. IV of the paper,
shared/paper/000_895b9ea056843c2c.txt; the test
tests/paper/test_settings.py pins every value against the sentence that states it).

The paper's wing takes them from here: its grids (paper/grids.py), Fig. 1-3, Table I and
the claims; nothing else spells them out, and nothing below the wing imports them (the
harness's own defaults, e.g. a ``Cell``'s budgets, are its own).
Team sizes and loss probabilities are tuples in the paper's order, a single loss
probability is a float, counts are ints.

May import: nothing of the project (the bottom of the wing).
"""
from __future__ import annotations

from typing import Any

__all__ = [
    "PAPER_C_MAX", "PAPER_EPISODES", "PAPER_EVAL_EPISODES", "PAPER_FIG1A_N", "PAPER_FIG1B_N", "PAPER_FIG1_P",
    "PAPER_FIG2_N", "PAPER_FIG2_P", "PAPER_FIG3_P", "PAPER_GROUPS", "PAPER_HORIZON", "PAPER_MAP", "PAPER_N",
    "PAPER_P", "PAPER_SEARCH_RADIUS", "PAPER_SETTINGS", "PAPER_TABLE1", "PAPER_TABLE1_N", "PAPER_TABLE1_P",
]

# Sec. IV, Simulation Setup (paper lines 707-708): "We consider robot teams of 20, 40, 60, 80, 90, and 100 robots.
# The robots are partitioned into Z=4 fixed groups. Communication loss probabilities of
# p in {0.2,0.4,0.6} are considered. Each training run consists of 2000 episodes, with a
# maximum horizon of 500 time steps per episode. For the safety filter, we set L=2 and
# C_max=500." ... "Each trained policy is evaluated over 100 randomly generated episodes."
PAPER_N: tuple[int, ...] = (20, 40, 60, 80, 90, 100)
PAPER_P: tuple[float, ...] = (0.2, 0.4, 0.6)
PAPER_GROUPS = 4
PAPER_EPISODES = 2000
PAPER_HORIZON = 500
PAPER_SEARCH_RADIUS = 2
PAPER_C_MAX = 500
PAPER_EVAL_EPISODES = 100

# Fig. 1 (fig:fig1, paper lines 714 and 719): (a) "teams of 20, 40, and 60 robots" against the decentralized
# baseline, (b) "larger teams of 80, 90, and 100 robots"; caption: "a 0.2 communication loss rate".
PAPER_FIG1A_N: tuple[int, ...] = (20, 40, 60)
PAPER_FIG1B_N: tuple[int, ...] = (80, 90, 100)
PAPER_FIG1_P = 0.2
# Fig. 2 (fig:fig2, paper line 723): "teams of 40 and 60 robots under communication loss
# probabilities p in {0.2,0.4,0.6}".
PAPER_FIG2_N: tuple[int, ...] = (40, 60)
PAPER_FIG2_P: tuple[float, ...] = PAPER_P
# Fig. 3 (fig:fig3) states no p; the bench shows it at the p of Fig. 1 and Table I.
PAPER_FIG3_P = 0.2
# Table I (tab:safety, paper lines 746 and 759-763): "team sizes 40, 60, 80, 90, and 100 under a communication loss
# probability of p=0.2"; N -> (collision rate, correction rate, mean candidates), rates as fractions.
PAPER_TABLE1_N: tuple[int, ...] = (40, 60, 80, 90, 100)
PAPER_TABLE1_P = 0.2
PAPER_TABLE1: dict[int, tuple[float, float, float]] = {
    40: (0.0, 0.0345, 3.79), 60: (0.0, 0.0548, 16.44), 80: (0.0, 0.0790, 24.15),
    90: (0.0, 0.0654, 35.63), 100: (0.0, 0.0734, 24.68),
}

# The paper's layouts are unpublished; this standard MovingAI warehouse map (5,699 free
# cells, bundled in envs/maps/) stands in for them at every N (docs/decisions/0012: the
# dense presets freeze the paper's filter).
PAPER_MAP = "warehouse-10-20-10-2-1"

# A cell's settings at the paper's budgets (bench/design/cells.py field names).
PAPER_SETTINGS: dict[str, Any] = dict(
    groups=PAPER_GROUPS, search_radius=PAPER_SEARCH_RADIUS, c_max=PAPER_C_MAX, episodes=PAPER_EPISODES,
    horizon=PAPER_HORIZON, eval_episodes=PAPER_EVAL_EPISODES, layout=PAPER_MAP,
)
