"""The claims' verdicts at the head of the paper's section of the index, and the claims'
checks grouped per claim under its claims entry (``paper.pages.index_claims``).

``ClaimsFront`` follows ``reports.pages.index.Front``: the generic index prints it under
the paper section's heading. It keeps the element id of each claim's block, so the verdict
table links to the block that ``checks_block`` writes further down the page.
"""
from __future__ import annotations

import html
from collections.abc import Callable

import pandas as pd

from paper.claims.claims import Claim
from paper.pages.index_claims import badge, grouped_checks_html
from reports.pages.index import TocItems, small_table
from reports.pages.layout import Anchors, scroll_box


class ClaimsFront:
    """The verdict of each claim (the paper's, then the run's own methods'), as a front."""

    def __init__(self, claims: list[Claim]) -> None:
        self.claims = claims
        self.paper = [c for c in claims if c.home == "paper"]
        self.own = [c for c in claims if c.home != "paper"]  # paper.claims.method_claims
        self.ids: dict[str, str] = {}

    def markdown(self) -> list[str]:
        lines = ["### Claims of the paper (Sec. IV)", "", "| claim | verdict |", "|---|---|"]
        lines += [f"| {c.key} | **{c.verdict}** |" for c in self.paper]
        if self.own:
            lines += ["", "### Methods of this run above each baseline", "", "| claim | verdict (run configurations) |",
                      "|---|---|"] + [f"| {c.key} | **{c.verdict}** |" for c in self.own]
        return lines + ["", "Details, numbers and tests: [claims.md](claims.md)", ""]

    def html(self, anchor: Anchors, toc: TocItems) -> list[str]:
        e = html.escape
        self.ids = {c.key: anchor(f"claim {c.key}") for c in self.claims}

        def verdicts(claims: list[Claim], caption: str) -> str:
            return scroll_box(small_table(["claim", "key", "verdict"], [
                [f"<a href='#{e(self.ids[c.key])}'>{e(c.name)}</a>", f"<code>{e(c.key)}</code>", badge(c.verdict)]
                for c in claims], caption))
        parts = [verdicts(self.paper, "Verdict of each claim at the paper's configurations (its checks per "
                          "configuration and execution mode under \"Claims of Sec. IV\" below)")]
        if self.own:
            parts.append(verdicts(self.own, "Methods of this run above each baseline: verdict at the run's "
                                  "configurations (its checks under \"Claims of Sec. IV\" below)"))
        return parts

    def checks_block(self, checks: pd.DataFrame) -> Callable[[Anchors, TocItems], str]:
        """The ``Entry.html_block`` of the claims entry: every claim's checks, grouped."""
        def block(anchor: Anchors, toc: TocItems) -> str:
            out, claim_toc = grouped_checks_html(checks, {c.key: c.verdict for c in self.claims},
                                                 lambda key: self.ids.get(key) or anchor(f"claim {key}"),
                                                 {c.key for c in self.own})
            toc += claim_toc
            return out
        return block
