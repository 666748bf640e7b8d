"""The claims' checks on ``index.html``, grouped so that a page of undecided checks is short.

One collapsible block per claim (``<details>``) whose summary line gives the claim's
verdict and how many checks have each verdict. Inside it, a table of the checks that were
decided (supported, undecided, contradicted, verified by construction) and one line
naming the configurations whose check had too few seeds: a smoke run, where nearly every
check is "not enough seeds", shows eight summary lines instead of ~70 table rows (over
12,000 px before). A block is open when its claim has a decided check. When every check
of a claim used the same test, the test is printed once above its table.
Pure: ``checks`` is ``paper.claims.page.claims_frame``'s frame.
"""
from __future__ import annotations

import html
from collections.abc import Callable, Collection, Mapping

import pandas as pd

from paper.claims.verdicts import NOT_ENOUGH, VERDICTS
from reports.pages.layout import html_table, scroll_box

ROW_COLUMNS = ["scope", "configuration", "execution", "verdict", "numbers", "test"]


def badge(verdict: str) -> str:
    return f"<b class='{verdict.replace(' ', '-')}'>{html.escape(verdict)}</b>"


def verdict_counts(verdicts: pd.Series) -> str:
    """"2 supported, 1 undecided, 12 not enough seeds" in the order of ``VERDICTS``."""
    counts = verdicts.value_counts()
    order = [v for v in VERDICTS if v in counts] + sorted(set(counts.index) - set(VERDICTS))
    return ", ".join(f"{int(counts[v])} {v}" for v in order)


def undecided_text(rows: pd.DataFrame) -> str:
    """The configurations of "not enough seeds" checks, each with its execution modes:
    "N = 40, p = 0.2 (argmax, sample); N = 60, p = 0.2 (argmax)" (scope "run" marked)."""
    parts: dict[str, list[str]] = {}
    for r in rows.itertuples(index=False):
        where = str(r.configuration) + (" [run]" if r.scope == "run" else "")
        modes = parts.setdefault(where, [])
        if str(r.execution) not in ("-", "") and str(r.execution) not in modes:
            modes.append(str(r.execution))
    return "; ".join(f"{k} ({', '.join(v)})" if v else k for k, v in parts.items())


def grouped_checks_html(checks: pd.DataFrame, claim_verdicts: Mapping[str, str],
                        claim_id: Callable[[str], str], own: Collection[str] = ()
                        ) -> tuple[str, list[tuple[str, str]]]:
    """HTML of every claim's checks, and the (name, element id) of each claim's block for
    the table of contents. ``claim_verdicts``: claim key -> its verdict (at the paper's
    configurations; for the keys in ``own``, claims of the run's own methods, at the run's);
    ``claim_id``: claim key -> the element id of its block."""
    e = html.escape
    out, toc = [], []
    for key, rows in checks.groupby("claim", sort=False):
        name = str(rows["name"].iloc[0])
        uid = claim_id(str(key))
        toc.append((name, uid))
        undecided = rows[rows["verdict"] == NOT_ENOUGH]
        decided = rows[rows["verdict"] != NOT_ENOUGH]
        verdict = claim_verdicts.get(str(key), "")
        summary = (f"<summary>{e(name)} <code>{e(str(key))}</code>: {badge(verdict) if verdict else ''} "
                   f"<span class='counts'>({e(verdict_counts(rows['verdict']))})</span></summary>")
        body = []
        if len(decided):
            cols = ROW_COLUMNS
            tests = decided["test"].astype(str).unique()
            if len(tests) == 1:
                body.append(f"<p class='thin'>Test: {e(tests[0])}</p>")
                cols = [c for c in cols if c != "test"]
            if (decided["scope"] == "paper").all():
                cols = [c for c in cols if c != "scope"]
            body.append(scroll_box(html_table(
                decided[cols].astype(str).reset_index(drop=True),
                ("" if key in own else "Claims of the paper's Sec. IV: ") + f"{name}: the checks that were decided",
                f"c_{key}"), wrap=True))
        if len(undecided):
            body.append(f"<p class='thin'><span class='not-enough-seeds'>Not enough seeds</span> (fewer "
                        f"than 3 on a side) at {len(undecided)} check(s): {e(undecided_text(undecided))}</p>")
        is_open = " open" if len(decided) else ""
        out.append(f"<details class='claim' id='{e(uid)}'{is_open}>{summary}{''.join(body)}</details>")
    return "\n".join(out), toc
