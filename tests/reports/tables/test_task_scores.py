"""Each task scored by its own score in every ranking of the report (docs/decisions/0235): a
lifelong cell by its throughput (goals reached per step), a one-shot cell by its success, and
never one against the other. The scores are built so that ranking a lifelong cell by success
(or pooling the two tasks) gives another answer than the right one."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from reports.stats import positive_ci
from reports.tables import leaderboard as lb
from reports.tables.leaders import leaders_display, leaders_frame, leaders_markdown, per_method_frame
from reports.tables.mapf import row_tasks, with_score
from reports.tables.success_table import success_markdown
from reports.tables.summary import summary_frame

# per seed (success, throughput): by success "lo" leads, by throughput "hi" does
HI = ((0.0, 0.50), (0.0, 0.52), (0.0, 0.54))
LO = ((0.3, 0.10), (0.3, 0.11), (0.3, 0.12))
SHOT = ((0.9, np.nan), (0.92, np.nan), (0.94, np.nan))  # a one-shot cell: no throughput


def _rows(method: str, n: int, mode: str, values: tuple[tuple[float, float], ...]) -> list[dict]:
    return [dict(cell_id=f"{method}-{n}-{s}", method=method, n_robots=n, loss_p=0.2, execution=mode, seed=s,
                 episode=0, success_rate=v, throughput=t, team_return=1.0, collision_rate=0.0,
                 correction_rate=0.0, fallback_rate=np.nan, mean_candidates=np.nan, payload_scalars_per_step=0.0,
                 safety_filter=False)
            for s, (v, t) in enumerate(values)]


def _lifelong() -> pd.DataFrame:
    """Two learned lifelong methods and PIBT at N = 4 and 8."""
    rows = []
    for n in (4, 8):
        rows += _rows("hi", n, "argmax", HI) + _rows("lo", n, "argmax", LO)
        rows += _rows("pibt", n, "planner", ((0.1, 0.8), (0.1, 0.8), (0.1, 0.8)))
    return pd.DataFrame(rows)


def _mixed() -> pd.DataFrame:
    """The lifelong run beside a one-shot method at N = 4: its success 0.92 is above every
    lifelong throughput, so pooling the scores would rank it first."""
    return pd.concat([_lifelong(), pd.DataFrame(_rows("shot", 4, "argmax", SHOT))], ignore_index=True)


def test_rows__a_row_with_a_throughput_is_lifelong_and_scored_by_it() -> None:
    ev = _mixed()
    scored = with_score(ev)
    life = row_tasks(ev).eq("lifelong")
    assert set(ev.loc[~life, "method"]) == {"shot"}
    assert np.array_equal(scored.loc[life, "score"], ev.loc[life, "throughput"])
    assert np.array_equal(scored.loc[~life, "score"], ev.loc[~life, "success_rate"])
    assert row_tasks(ev.drop(columns="throughput")).eq("one-shot").all()  # a store from before the column


def test_leaderboard__a_lifelong_cell_ranks_by_throughput_and_each_task_apart() -> None:
    board = lb.leaderboard_frame(_mixed()).set_index(["task", "n_robots", "method"])
    assert board.loc[("lifelong", 4, "hi"), "throughput"] == pytest.approx(0.52)
    # by throughput pibt (0.8) > hi (0.52) > lo (0.11); by success lo would lead
    assert [board.loc[("lifelong", 4, m), "rank"] for m in ("pibt", "hi", "lo")] == [1, 2, 3]
    assert board.loc[("one-shot", 4, "shot"), "rank"] == 1  # ranked among one-shot cells only
    assert np.isnan(board.loc[("one-shot", 4, "shot"), "throughput"])
    shown = lb.leaderboard_display(lb.leaderboard_frame(_mixed()))
    assert list(shown.columns[:4]) == ["task", "N", "p", "execution"]  # no row holds both tasks
    assert shown.loc[shown["task"] == "one-shot", "shot"].iloc[0].startswith("92.0% [")
    life = shown[(shown["task"] == "lifelong") & (shown["N"] == 4) & (shown["execution"] == "argmax")].iloc[0]
    assert life["hi"].startswith("0.52 ") and "%" not in life["hi"]


def test_leaderboard_page__names_each_task_s_score_and_never_pools_them() -> None:
    ev = _mixed()
    board = lb.leaderboard_frame(ev)
    iqm, poi = lb.aggregate_frame(ev)
    md = lb.leaderboard_markdown(board, iqm, poi, lb.safety_frame(ev))
    assert "## One-shot cells: ranked by success" in md
    assert "## Lifelong cells: ranked by throughput (goals reached per step)" in md
    assert "## Across configurations: lifelong cells" in md and "## Across configurations: one-shot cells" in md
    # the lifelong aggregates are over throughput: hi above lo with certainty, and in goals per step
    life = iqm[iqm["task"] == "lifelong"].set_index("method")
    assert life.loc["hi", "iqm"] == pytest.approx(0.52) and life.loc["lo", "iqm"] == pytest.approx(0.11)
    pair = poi[(poi["task"] == "lifelong") & (poi["method"] == "hi") & (poi["over"] == "lo")]
    assert pair["poi"].iloc[0] == pytest.approx(1.0)
    assert set(iqm.loc[iqm["task"] == "one-shot", "method"]) == {"shot"}  # only its own task's rows


def test_leaders__a_lifelong_race_is_won_on_throughput_with_a_margin_in_goals_per_step() -> None:
    ev = _lifelong()
    frame = leaders_frame(ev)
    row = frame[frame["n_robots"] == 4].iloc[0]
    assert (row["task"], row["leader"], row["runner_up"]) == ("lifelong", "hi", "lo")  # success picks "lo"
    assert row["leader_score"] == pytest.approx(0.52) and row["margin"] == pytest.approx(0.41)
    _, l1, u1 = positive_ci(np.array([t for _, t in HI]))
    _, l2, u2 = positive_ci(np.array([t for _, t in LO]))
    assert row["margin_lo"] == pytest.approx(0.41 - np.hypot(0.52 - l1, u2 - 0.11))
    assert row["gap_to_planner"] == pytest.approx(0.52 - 0.8)
    assert "leader_success" not in frame  # a throughput is never filed as a success
    per = per_method_frame(ev, frame).set_index("method")
    assert per.loc["hi", "leads"] == 2 and per.loc["hi", "gap_max"] == pytest.approx(0.52 - 0.8)
    md = leaders_markdown(frame, per.reset_index(), ["lifelong"])
    assert "highest mean throughput" in md and "highest mean success" not in md
    assert "| 4 | hi 0.52 > lo 0.11 (+0.410 goals/step [" in md
    assert "throughput − best planner, goals/step" in md
    assert "goals/step" in leaders_display(frame).iloc[0, 2]


def test_leaders__a_mixed_run_races_each_task_apart() -> None:
    frame = leaders_frame(_mixed())
    at4 = frame[(frame["n_robots"] == 4)].set_index("task")
    assert at4.loc["one-shot", "leader"] == "shot" and at4.loc["one-shot", "runner_up"] == ""
    assert at4.loc["lifelong", "leader"] == "hi"
    md = leaders_markdown(frame, per_method_frame(_mixed(), frame), ["one-shot", "lifelong"])
    assert "## argmax, lifelong cells (throughput)" in md and "## argmax, one-shot cells (success)" in md


def test_figures__a_lifelong_run_draws_throughput_and_a_mixed_run_each_task() -> None:
    ev = _lifelong()
    figures = dict(lb.score_figures(lb.leaderboard_frame(ev), ev))
    assert list(figures) == ["throughput_vs_n", "throughput_vs_p", "performance_profiles"]
    caption = figures["performance_profiles"].caption
    assert "with throughput above tau" in caption and "success" not in caption
    ax = figures["performance_profiles"].fig.axes[0]
    hi = next(line for line in ax.lines if line.get_label() == "hi")
    x, y = hi.get_xdata(), hi.get_ydata()
    assert x.max() == pytest.approx(0.8)  # tau up to the run's largest throughput (PIBT's)
    assert y[x < 0.5].min() == 1.0 and y[x > 0.54].max() == 0.0  # its throughputs, 0.50-0.54, not its 0 success
    wider = ev.assign(throughput=np.where(ev["n_robots"] == 8, 2 * ev["throughput"], ev["throughput"]))
    vs_p = dict(lb.score_figures(lb.leaderboard_frame(wider), wider))["throughput_vs_p"].fig
    assert all(ax.get_ylim()[1] >= 1.6 for ax in vs_p.axes if ax.has_data())  # N = 8's 1.6 is not cut off
    mixed = dict(lb.score_figures(lb.leaderboard_frame(_mixed()), _mixed()))
    assert list(mixed) == ["success_vs_n", "success_vs_p", "performance_profiles", "throughput_vs_n",
                           "throughput_vs_p", "performance_profiles_lifelong"]
    assert "with success above tau" in mixed["performance_profiles"].caption
    assert "over the 1 configurations" in mixed["performance_profiles"].caption  # N = 4: the one-shot cell's


def test_success_table__a_lifelong_cell_shows_its_throughput_in_a_table_of_its_own() -> None:
    ev = _mixed()
    cells = (ev.drop_duplicates("cell_id")[["cell_id", "method", "n_robots", "loss_p"]]
             .assign(status="done", executions=lambda c: np.where(c["method"] == "pibt", "planner", "argmax"),
                     safety_filter=False,
                     config_json=lambda c: np.where(c["method"] == "shot", "{}", '{"task": "lifelong"}')))
    md = success_markdown(summary_frame(ev, cells), cells)
    one_shot, lifelong = md.split("## Lifelong cells: throughput")
    assert "## One-shot cells: success rate" in one_shot and "92.0%" in one_shot and "| hi |" not in one_shot
    hi = next(line for line in lifelong.splitlines() if "| hi |" in line)
    assert "0.52 [" in hi and "%" not in hi  # its throughput, not its 0.0% success
    assert "Throughput (goals reached per step" in lifelong


def test_ordering__each_task_signs_on_its_own_score_and_configurations_never_pool() -> None:
    from reports.tables.ordering import ordering_frame, ordering_markdown
    rows = []
    for n in range(2, 9):  # 7 configurations, lifelong and one-shot at each: 7 of 7 decides at 0.0125
        rows += _rows("hi", n, "argmax", HI) + _rows("lo", n, "argmax", LO)  # lifelong: hi above on throughput
        rows += [{**r, "cell_id": "s" + r["cell_id"], "throughput": np.nan, "success_rate": v}  # one-shot: lo above
                 for m, v in (("hi", 0.2), ("lo", 0.6)) for r in _rows(m, n, "argmax", SHOT)]
    frame = ordering_frame(pd.DataFrame(rows)).set_index("task")
    assert frame.loc["lifelong", ["method", "over", "above", "below", "configurations", "verdict"]].tolist() == \
        ["hi", "lo", 7, 0, 7, "above"]
    assert frame.loc["one-shot", ["method", "over", "above", "below", "configurations", "verdict"]].tolist() == \
        ["lo", "hi", 7, 0, 7, "above"]
    md = ordering_markdown(frame.reset_index())
    assert "| lifelong (throughput) | argmax | hi | lo | 7 / 0 (0) of 7 |" in md
    assert "| one-shot (success) | argmax | lo | hi | 7 / 0 (0) of 7 |" in md


def test_robustness__a_lifelong_seed_collapses_on_throughput_and_seeds_md_shows_its_throughput() -> None:
    from reports.tables.robustness import robustness_frame, robustness_markdown, seeds_frame, seeds_markdown
    # succeeds half the time; one seed below 10% of PIBT's 0.8 (0.08), one just above it (but below 0.1)
    weak = ((0.5, 0.05), (0.5, 0.09), (0.5, 0.3))
    ev = pd.concat([_lifelong(), pd.DataFrame(_rows("weak", 4, "argmax", weak) + _rows("weak", 8, "argmax", weak))],
                   ignore_index=True)
    learned = ev[ev["method"] != "pibt"].drop_duplicates("cell_id")
    train = pd.DataFrame([{"cell_id": c, "method": m, "n_robots": n, "episode": e, "team_return": float(e)}
                          for c, m, n in zip(learned["cell_id"], learned["method"], learned["n_robots"], strict=True)
                          for e in range(60)])
    frame = robustness_frame(train, ev).set_index(["method", "n_robots"])
    # by success (< 10%) "hi" would be 3/3 collapsed and "weak" 0/3: by throughput it is the other way
    assert frame.loc[("hi", 4), "collapsed"] == 0 and frame.loc[("weak", 4), "collapsed"] == 1
    assert set(frame["task"]) == {"lifelong"}
    assert "10% of the best mean throughput" in robustness_markdown(frame.reset_index())
    seeds = seeds_frame(train, ev)
    row = seeds[(seeds["method"] == "weak") & (seeds["n_robots"] == 4)].iloc[0]
    assert (row["task"], row["success_by_seed"], row["collapsed"]) == ("lifelong", "0.05, 0.09, 0.3", 1)
    assert row["mean"] == pytest.approx(0.44 / 3)
    md = seeds_markdown(seeds)
    assert "| Weak | 4 | 0.2 | argmax | lifelong | 0.05, 0.09, 0.3 | 0.147 |" in md.replace("weak", "Weak")


def test_success_figure__no_band_where_the_interval_is_not_trusted_and_a_hollow_marker_instead() -> None:
    """Decision 0233 in the figures: a collapsed configuration (one seed at 0, two high: coverage
    under 93%) is drawn as a hollow point with no band; a steady one keeps its band."""
    ev = pd.concat([pd.DataFrame(_rows("m", 4, "argmax", ((0.80, np.nan), (0.82, np.nan), (0.84, np.nan)))),
                    pd.DataFrame(_rows("m", 8, "argmax", ((0.0, np.nan), (0.95, np.nan), (0.97, np.nan))))],
                   ignore_index=True)
    board = lb.leaderboard_frame(ev)
    assert [lb.trusted(c) for c in board.sort_values("n_robots")["success_cov"]] == [True, False]
    built = dict(lb.score_figures(board, ev))["success_vs_n"]
    ax = built.fig.axes[0]
    (band,) = ax.collections
    xs = {round(float(x), 6) for path in band.get_paths() for x in path.vertices[:, 0]}
    assert 4.0 in xs and 8.0 not in xs  # the band stops at the last trusted point
    hollow = [line for line in ax.lines if line.get_linestyle() == "None" and len(line.get_xdata())]
    assert [list(line.get_xdata()) for line in hollow] == [[8.0]] and hollow[0].get_markerfacecolor() == "white"
    assert "no band and a hollow marker" in built.caption
