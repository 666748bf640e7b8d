"""paper/settings.py against the sentences of the paper that state each setting.

Each quote is copied verbatim from the paper's source (line numbers of
shared/paper/000_895b9ea056843c2c.txt); the numbers are read out of the quote, so a
constant that drifts from the paper's text fails here.
"""
from __future__ import annotations

import re

import paper.settings as paper
from envs.layouts import bundled_maps

# Sec. IV, Simulation Setup (line 707).
SETUP = ("We consider robot teams of $20$, $40$, $60$, $80$, $90$, and $100$ robots. The robots are partitioned "
         "into $Z=4$ fixed groups. Communication loss probabilities of $p\\in\\{0.2,0.4,0.6\\}$ are considered. "
         "Each training run consists of $2000$ episodes, with a maximum horizon of $500$ time steps per episode. "
         "For the safety filter, we set $L=2$ and $C_{\\max}=500$.")
EVAL = "Each trained policy is evaluated over $100$ randomly generated episodes."  # line 708
# line 714 (Fig. 1 (a) and (b)) and the caption of fig:fig1 (line 719)
FIG1A = "compares the proposed method with the fully decentralized baseline for teams of $20,40$, and $60$ robots"
FIG1B = "reports the training results of the proposed method for larger teams of  $80$, $90$, and $100$ robots"
FIG1_CAPTION = "under different robot team sizes, with a 0.2 communication loss rate."
# line 723 (Fig. 2)
FIG2 = ("We compare the proposed method with IC3Net for team sizes of $40$ and $60$ robots and communication "
        "loss probabilities $p\\in\\{0.2,0.4,0.6\\}$.")
# line 746 (Table I) and its rows, lines 759-763 (N & collision & correction & mean candidates)
TABLE1 = ("safety-related metrics for robot team sizes $40,60,80,90$, and $100$ under a communication loss "
          "probability of $p=0.2$.")
TABLE1_ROWS = """40  & 0.00\\% & 3.45\\% & 3.79  \\\\
60  & 0.00\\% & 5.48\\% & 16.44 \\\\
80  & 0.00\\% & 7.90\\% & 24.15 \\\\
90  & 0.00\\% & 6.54\\% & 35.63 \\\\
100 & 0.00\\% & 7.34\\% & 24.68 \\\\"""


def numbers(text: str) -> list[float]:
    return [float(x) for x in re.findall(r"\d+(?:\.\d+)?", text)]


def ints(text: str) -> tuple[int, ...]:
    return tuple(int(x) for x in numbers(text))


def after(text: str, key: str) -> float:
    """The number right after ``key`` in ``text``."""
    m = re.search(re.escape(key) + r"\s*(\d+(?:\.\d+)?)", text)
    assert m is not None, key
    return float(m.group(1))


def test_paper__simulation_setup() -> None:
    teams = SETUP[:SETUP.index("robots.")]
    assert paper.PAPER_N == ints(teams)
    assert paper.PAPER_P == tuple(numbers(SETUP[SETUP.index("\\{"):SETUP.index("\\}")]))
    assert paper.PAPER_GROUPS == after(SETUP, "$Z=")
    assert paper.PAPER_EPISODES == after(SETUP, "consists of $")
    assert paper.PAPER_HORIZON == after(SETUP, "horizon of $")
    assert paper.PAPER_SEARCH_RADIUS == after(SETUP, "$L=")
    assert paper.PAPER_C_MAX == after(SETUP, "$C_{\\max}=")
    assert paper.PAPER_EVAL_EPISODES == after(EVAL, "over $")


def test_paper__figures_and_table_settings() -> None:
    assert paper.PAPER_FIG1A_N == ints(FIG1A)
    assert paper.PAPER_FIG1B_N == ints(FIG1B)
    assert paper.PAPER_FIG1_P == after(FIG1_CAPTION, "with a")
    assert paper.PAPER_FIG2_N == ints(FIG2[FIG2.index("team sizes"):FIG2.index("robots")])
    assert paper.PAPER_FIG2_P == tuple(numbers(FIG2[FIG2.index("\\{"):]))
    assert paper.PAPER_TABLE1_N == ints(TABLE1[:TABLE1.index("under")])
    assert paper.PAPER_TABLE1_P == after(TABLE1, "$p=")
    rows = {int(r[0]): (r[1] / 100, r[2] / 100, r[3]) for r in map(numbers, TABLE1_ROWS.splitlines())}
    assert set(paper.PAPER_TABLE1) == set(paper.PAPER_TABLE1_N)
    for n, row in rows.items():
        assert paper.PAPER_TABLE1[n] == tuple(round(v, 6) for v in row), n


def test_paper__types_and_the_cell_settings() -> None:
    for name in ("PAPER_N", "PAPER_FIG1A_N", "PAPER_FIG1B_N", "PAPER_FIG2_N", "PAPER_TABLE1_N"):
        assert all(type(v) is int for v in getattr(paper, name)), name
    for name in ("PAPER_P", "PAPER_FIG2_P"):
        assert all(type(v) is float for v in getattr(paper, name)), name
    for name in ("PAPER_FIG1_P", "PAPER_FIG3_P", "PAPER_TABLE1_P"):
        assert type(getattr(paper, name)) is float, name
    assert paper.PAPER_MAP in bundled_maps()  # the stand-in layout ships with the package
    assert paper.PAPER_SETTINGS == dict(
        groups=paper.PAPER_GROUPS, search_radius=paper.PAPER_SEARCH_RADIUS, c_max=paper.PAPER_C_MAX,
        episodes=paper.PAPER_EPISODES, horizon=paper.PAPER_HORIZON, eval_episodes=paper.PAPER_EVAL_EPISODES,
        layout=paper.PAPER_MAP)
