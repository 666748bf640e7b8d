"""Who leads where (reports/tables/leaders.py): leader, runner-up, margin with its CI,
the planner kept apart, and the page's wording, on scores worked out by hand."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats as sps

from reports.stats import rate_ci
from reports.tables.leaders import (
    COLUMNS,
    PER_METHOD_COLUMNS,
    leaders_display,
    leaders_frame,
    leaders_markdown,
    per_method_frame,
)


def _evals(rows: list[tuple[str, int, float, str, int, float]]) -> pd.DataFrame:
    """Eval rows (method, N, p, execution, seed, success), one episode each."""
    return pd.DataFrame([dict(method=m, n_robots=n, loss_p=p, execution=e, seed=s, success_rate=v, episode=0)
                         for m, n, p, e, s, v in rows],
                        columns=["method", "n_robots", "loss_p", "execution", "seed", "success_rate", "episode"])


def _seeds(method: str, n: int, p: float, mode: str, values: tuple[float, ...]) -> list:
    return [(method, n, p, mode, s, v) for s, v in enumerate(values)]


A, B, C = (0.88, 0.9, 0.92), (0.28, 0.3, 0.32), (0.58, 0.6, 0.62)
ONE = (1.0, 1.0, 1.0)


def test_leaders__leader_runner_up_and_the_square_and_add_margin() -> None:
    ev = _evals(_seeds("b", 4, 0.2, "argmax", B) + _seeds("a", 4, 0.2, "argmax", A)
                + _seeds("c", 4, 0.2, "argmax", C) + _seeds("pibt", 4, 0.2, "planner", ONE))
    row = leaders_frame(ev).iloc[0]
    assert (row["leader"], row["runner_up"], row["methods"]) == ("a", "c", 3)  # the planner is not in the race
    assert row["leader_success"] == pytest.approx(0.9) and row["runner_up_success"] == pytest.approx(0.6)
    assert row["margin"] == pytest.approx(0.3)
    # Newcombe's square-and-add of the two rates' logit t intervals
    _, la, ua = rate_ci(np.array(A))
    _, lc, uc = rate_ci(np.array(C))
    assert row["margin_lo"] == pytest.approx(0.3 - np.hypot(0.9 - la, uc - 0.6))
    assert row["margin_hi"] == pytest.approx(0.3 + np.hypot(ua - 0.9, 0.6 - lc))
    assert -1.0 <= row["margin_lo"] < 0.3 < row["margin_hi"] <= 1.0
    # the gap to the planner: 0.9 - 1.0; the planner has no spread, so the leader's own interval
    assert row["planner"] == "pibt" and row["gap_to_planner"] == pytest.approx(-0.1)
    assert (row["gap_lo"], row["gap_hi"]) == (pytest.approx(la - 1.0), pytest.approx(ua - 1.0))


def test_leaders__one_learned_method_has_no_runner_up_and_each_mode_is_its_own_race() -> None:
    ev = _evals(_seeds("a", 4, 0.2, "argmax", A) + _seeds("a", 4, 0.2, "sample", B)
                + _seeds("b", 4, 0.2, "sample", C) + _seeds("a", 8, 0.4, "argmax", B))
    f = leaders_frame(ev).set_index(["n_robots", "execution"])
    assert f.loc[(4, "argmax"), "runner_up"] == "" and np.isnan(f.loc[(4, "argmax"), "margin"])
    assert f.loc[(4, "sample"), "leader"] == "b"  # in sample mode b beats a
    assert f.loc[(8, "argmax"), "leader"] == "a" and f.loc[(8, "argmax"), "planner"] == ""
    assert len(f) == 3  # no row for (8, sample): nothing ran there
    page = _page(ev)
    assert "2 configurations have one learned method. Against the planners: no planner ran at these" in page


def test_leaders__a_margin_stays_inside_plus_minus_one_and_an_unseparated_lead_is_written_approx() -> None:
    wide = (0.0, 1.0, 0.05)  # a noisy leader: its margin's Welch t interval would reach past +-100 pp
    ev = _evals(_seeds("a", 4, 0.2, "argmax", wide) + _seeds("b", 4, 0.2, "argmax", (0.3, 0.3, 0.3)))
    row = leaders_frame(ev).iloc[0]
    assert row["leader"] == "a" and -1.0 <= row["margin_lo"] < -0.25 and 0.6 < row["margin_hi"] <= 1.0
    page = _page(ev)
    assert f"a 35.0% ≈ b 30.0% (+5.0 pp [{100 * row['margin_lo']:+.1f}, {100 * row['margin_hi']:+.1f}])" in page
    assert "a leads 1 of 1 configuration with two or more learned methods (0 by a margin whose CI excludes 0)" in page


def test_leaders__the_index_page_table_has_one_narrow_cell_per_configuration() -> None:
    ev = _evals(_seeds("a", 4, 0.2, "argmax", A) + _seeds("b", 4, 0.2, "argmax", B)
                + _seeds("a", 4, 0.6, "argmax", B) + _seeds("pibt", 4, 0.2, "planner", ONE)
                + _seeds("pibt", 4, 0.6, "planner", ONE))
    table = leaders_display(leaders_frame(ev))
    assert list(table.columns) == ["execution", "N", "p = 0.2", "p = 0.6"]
    assert table.loc[0, "p = 0.2"] == "a > b (+60.0 pp)"  # the index page's narrow cell
    assert table.loc[0, "p = 0.6"] == "a (only learned method)"


def test_leaders__an_empty_run_has_an_empty_page() -> None:
    empty = _evals([])
    assert leaders_frame(empty).empty and leaders_display(leaders_frame(empty)).empty
    assert list(leaders_frame(empty).columns) == COLUMNS  # leaders.csv has its header even so
    assert list(per_method_frame(empty, leaders_frame(empty)).columns) == PER_METHOD_COLUMNS
    intro = PAGE.split("\n")[:4]  # title, blank, what the page says, blank
    assert _page(empty) == "\n".join([*intro, "No learned method was evaluated yet.", ""])


# Every case on one page: separated and unseparated leads, a tie broken by name, a lone
# learned method, a missing configuration, planners below, level with and above the leader.
PAGE_EVALS = (_seeds("b", 4, 0.2, "argmax", B) + _seeds("a", 4, 0.2, "argmax", A)
              + _seeds("a", 4, 0.2, "sample", B) + _seeds("b", 4, 0.2, "sample", C)
              + _seeds("pibt", 4, 0.2, "planner", ONE)
              + _seeds("a", 4, 0.6, "argmax", C) + _seeds("pibt", 4, 0.6, "planner", (0.2, 0.2, 0.2))
              + _seeds("pibt", 8, 0.2, "planner", ONE) + _seeds("b", 8, 0.2, "argmax", ONE)
              + _seeds("a", 8, 0.2, "argmax", ONE)
              + _seeds("c", 8, 0.2, "sample", A) + _seeds("a", 8, 0.2, "sample", B)
              + _seeds("c", 8, 0.6, "sample", A) + _seeds("a", 8, 0.6, "sample", B))
# Margins: Newcombe's square-and-add of the two rates' logit t intervals (3 seeds each: none
# separated, the test above checks the formula); gaps to the planner -0.1, +0.4, -0.7 (b in
# argmax, a in sample) and -0.4; the ties at 1.0 have no variance. Per method, b's argmax gap
# at N = 8 is +0.0 (below at neither), a's at N = 4, p = 0.6 is above.
PAGE = "\n".join((
    '# Who leads where',
    '',
    'Per configuration (team size N, loss probability p) and learned execution mode: the learned '
    "method with the highest mean success over seeds, then the runner-up, and the leader's margin in "
    "percentage points [95% CI over seeds: the square-and-add of the two rates' logit t intervals, "
    'inside ±100 points by construction]. ">" where that interval excludes 0, "≈" where it does not. '
    'The leader is picked by its mean and the intervals are pointwise (not corrected for the number '
    'of configurations; where no method is better, ">" appears at under 5% of them, simulated): this '
    'describes the run, the calibrated verdicts are in claims.md. Planners are listed apart, as a '
    'reference (PIBT plans with full information).',
    '',
    '## Per method',
    '',
    'Per learned method and mode: how many of the configurations it shares with another learned '
    'method it leads (and by a margin whose CI excludes 0), and at the configurations it shares with '
    "a planner, its own success minus the best planner's (the range of the means, and at how many "
    'the 95% CI lies below or above 0).',
    '',
    '| mode | method | leads | by a separated margin | success − best planner, pp | CI below / above 0 |',
    '|---|---|---|---|---|---|',
    '| argmax | a | 2 of 2 | 1 | -10.0 to +40.0 | 1 / 1 of 3 |',
    '| argmax | b | 0 of 2 | 0 | -70.0 to +0.0 | 1 / 0 of 2 |',
    '| sample | a | 0 of 3 | 0 | -70.0 | 2 / 0 of 2 |',
    '| sample | b | 1 of 1 | 1 | -40.0 | 1 / 0 of 1 |',
    '| sample | c | 2 of 2 | 2 | -10.0 | 1 / 0 of 1 |',
    '',
    '## argmax',
    '',
    '| N | p = 0.2 | p = 0.6 |',
    '|---|---|---|',
    '| 4 | a 90.0% > b 30.0% (+60.0 pp [+52.0, +66.3]) | a 60.0% (only learned method) |',
    '| 8 | a 100.0% ≈ b 100.0% (+0.0 pp [+0.0, +0.0]) | — |',
    '',
    'a leads 2 of 2 configurations with two or more learned methods (1 by a margin whose CI excludes '
    "0); 1 configuration has one learned method. Against the planners: the leading learned method's "
    "success minus the best planner's (PIBT: 20.0% to 100.0%) is -10.0 to +40.0 pp; its CI lies "
    'below 0 at 1 and above 0 at 1 of the 3 configurations with a planner.',
    '',
    '## sample',
    '',
    '| N | p = 0.2 | p = 0.6 |',
    '|---|---|---|',
    '| 4 | b 60.0% > a 30.0% (+30.0 pp [+22.8, +36.8]) | — |',
    '| 8 | c 90.0% > a 30.0% (+60.0 pp [+52.0, +66.3]) | c 90.0% > a 30.0% (+60.0 pp [+52.0, +66.3]) |',
    '',
    'c leads 2 of 3 configurations with two or more learned methods (2 by a margin whose CI excludes '
    '0); b leads 1 of 3 configurations with two or more learned methods (1 by a margin whose CI '
    'excludes 0). Where another method than c leads: N = 4, p = 0.2 (b >). Against the planners: the '
    "leading learned method's success minus the best planner's (PIBT: 100.0%) is -40.0 to -10.0 pp; "
    'its CI lies below 0 at 2 and above 0 at 0 of the 2 configurations with a planner.',
    '',
))


def _page(ev: pd.DataFrame) -> str:
    f = leaders_frame(ev)
    return leaders_markdown(f, per_method_frame(ev, f))


def test_leaders__the_page_word_for_word() -> None:
    assert _page(_evals(PAGE_EVALS)) == PAGE


def test_leaders__per_method_counts_a_lone_method_and_one_without_a_planner_apart() -> None:
    ev = _evals(_seeds("a", 4, 0.2, "argmax", A) + _seeds("b", 8, 0.2, "argmax", B)
                + _seeds("c", 8, 0.2, "argmax", C) + _seeds("pibt", 4, 0.2, "planner", ONE))
    f = per_method_frame(ev, leaders_frame(ev))
    assert list(f.columns) == PER_METHOD_COLUMNS
    assert f.set_index("method")[["configurations", "contested", "leads", "with_planner"]].to_dict("index") == {
        "a": dict(configurations=1, contested=0, leads=0, with_planner=1),
        "b": dict(configurations=1, contested=1, leads=0, with_planner=0),
        "c": dict(configurations=1, contested=1, leads=1, with_planner=0)}
    page = _page(ev)
    assert "| argmax | a | — (alone) | — | -10.0 | 1 / 0 of 1 |" in page  # a tight leader: below PIBT
    assert "| argmax | b | 0 of 1 | 0 | — | — |" in page


def test_leaders__rows_by_configuration_and_modes_in_report_order() -> None:
    ev = _evals(_seeds("a", 8, 0.2, "sample@0.5", A) + _seeds("a", 4, 0.6, "sample@1.5", A)
                + _seeds("a", 4, 0.2, "argmax", A) + _seeds("a", 4, 0.2, "sample@0.5", A))
    f = leaders_frame(ev)
    assert list(zip(f["n_robots"], f["loss_p"], f["execution"], strict=True)) == [
        (4, 0.2, "argmax"), (4, 0.2, "sample@0.5"), (4, 0.6, "sample@1.5"), (8, 0.2, "sample@0.5")]
    shown = leaders_display(f)  # sample@1.5 before sample@0.5 (decreasing T), not alphabetical
    assert list(zip(shown["execution"], shown["N"], strict=True)) == [
        ("argmax", 4), ("sample@1.5", 4), ("sample@0.5", 4), ("sample@0.5", 8)]
    assert shown.loc[0, "p = 0.6"] == ""  # nothing ran there


def test_leaders__ties_go_to_the_method_listed_first_and_so_do_equal_counts() -> None:
    ev = _evals(_seeds("decentralized", 4, 0.2, "argmax", ONE) + _seeds("hierarchical", 4, 0.2, "argmax", ONE)
                + _seeds("decentralized", 8, 0.2, "argmax", A) + _seeds("hierarchical", 8, 0.2, "argmax", B)
                + _seeds("pibt", 4, 0.2, "planner", ONE) + _seeds("astar", 8, 0.2, "planner", ONE))
    f = leaders_frame(ev)
    assert list(f["leader"]) == ["hierarchical", "decentralized"]  # the paper's method is listed first
    assert list(per_method_frame(ev, f)["method"]) == ["hierarchical", "decentralized"]  # legend order, not A-Z
    page = leaders_markdown(f, per_method_frame(ev, f))
    assert page.index("Hierarchical (ours) leads 1 of 2") < page.index("Decentralized leads 1 of 2")
    assert "the best planner's (PIBT, astar: 100.0%)" in page  # every planner named once
    assert "Where another method than Hierarchical (ours) leads: N = 8, p = 0.2 (Decentralized >)." in page


def test_leaders__the_configurations_where_another_method_than_the_most_leading_one_leads() -> None:
    ev = _evals(_seeds("a", 4, 0.2, "argmax", A) + _seeds("b", 4, 0.2, "argmax", B)
                + _seeds("a", 8, 0.2, "argmax", A) + _seeds("b", 8, 0.2, "argmax", B)
                + _seeds("b", 8, 0.6, "argmax", (0.0, 1.0, 0.05)) + _seeds("a", 8, 0.6, "argmax", (0.3, 0.3, 0.3))
                + _seeds("b", 20, 0.2, "argmax", A) + _seeds("a", 20, 0.2, "argmax", B)
                + _seeds("a", 20, 0.6, "argmax", A) + _seeds("b", 20, 0.6, "argmax", B)
                + _seeds("b", 4, 0.6, "argmax", A))  # b alone: not a change of leader
    page = _page(ev)
    assert (" Where another method than a leads: N = 8, p = 0.6 (b ≈); N = 20, p = 0.2 (b >). "
            "Against the planners") in page
    one = _page(_evals(_seeds("a", 4, 0.2, "argmax", A) + _seeds("b", 4, 0.2, "argmax", B)))
    assert "Where another" not in one  # one leader everywhere: nothing to add


@pytest.mark.parametrize("sds", [(0.1, 0.1), (0.1, 0.3), (0.1, 0.3, 0.1)])
def test_leaders__a_lead_is_rarely_marked_separated_when_no_method_is_better(sds: tuple[float, ...]) -> None:
    """Simulated calibration of ">": 1,500 configurations where every learned method has the
    same mean success (per-seed means normal around 0.5, 3 seeds, the given spreads). The
    leader is picked by its mean, yet its margin's CI excludes 0 at 3.7%, 4.8% and 2.8% of
    them: at most 5% plus two Monte-Carlo standard errors (0.56 points)."""
    rng = np.random.default_rng(7)
    rows = [(f"m{i}", n, 0.2, "argmax", s, v) for n in range(1500) for i, sd in enumerate(sds)
            for s, v in enumerate(rng.normal(0.5, sd, 3))]
    frame = leaders_frame(_evals(rows))
    assert len(frame) == 1500
    rate = float((frame["margin_lo"] > 0).mean())
    assert 0.005 < rate <= 0.05 + 2 * np.sqrt(0.05 * 0.95 / 1500)  # and not 0: the interval is not vacuous


def test_ordering__sign_test_of_each_pair_across_configurations() -> None:
    from reports.tables.ordering import ordering_frame, ordering_markdown

    rows = []
    for k, n in enumerate((10, 20, 30, 40, 50, 60, 70, 80)):  # a above b at 8 of 8, c above b at 5 of 8
        rows += _seeds("a", n, 0.2, "argmax", A) + _seeds("b", n, 0.2, "argmax", B)
        rows += _seeds("c", n, 0.2, "argmax", C if k < 5 else (0.0, 0.1, 0.2))
        rows += _seeds("pibt", n, 0.2, "planner", ONE)  # planners are not ordered
    f = ordering_frame(_evals(rows)).set_index(["method", "over"])
    assert set(f.index) == {("a", "b"), ("a", "c"), ("c", "b")}
    ab = f.loc[("a", "b")]
    assert (ab["above"], ab["below"], ab["configurations"]) == (8, 0, 8)
    assert ab["p_above"] == pytest.approx(0.5**8) and ab["verdict"] == "above"
    cb = f.loc[("c", "b")]
    assert (cb["above"], cb["below"]) == (5, 3) and cb["verdict"] == "undecided"
    assert cb["p_above"] == pytest.approx(sps.binom.sf(4, 8, 0.5))
    assert "| argmax | a | b | 8 / 0 (0) of 8 | 0.0039 | above |" in ordering_markdown(ordering_frame(_evals(rows)))
