"""index.html for a referee (item 6): a table of contents whose links land on
headings, a layout that uses the window with tables scrolling inside their own box, and
the claims' checks grouped so that undecided ("not enough seeds") checks take one line."""
from __future__ import annotations

import re
import shutil
import subprocess
from html.parser import HTMLParser

import pandas as pd
import pytest

from paper.claims.claims import Check, Claim
from paper.claims.page import claims_frame
from paper.pages.front import ClaimsFront
from paper.pages.index_claims import undecided_text, verdict_counts
from reports.pages.index import Entry, IndexData, Part, index_html


class _Page(HTMLParser):
    """Ids, in-page links (inside the nav or not), tables with their enclosing div classes,
    and each <details> with its open flag and the number of table rows inside it."""

    def __init__(self) -> None:
        super().__init__()
        self.ids: list[str] = []
        self.nav_links: list[str] = []
        self.links: list[str] = []
        self.headings: list[str] = []  # ids of h2/h3
        self.table_parents: list[str] = []
        self.details: list[dict] = []
        self._stack: list[tuple[str, dict]] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if "id" in a:
            self.ids.append(a["id"])
        if tag in ("h2", "h3") and "id" in a:
            self.headings.append(a["id"])
        if tag == "a" and a.get("href", "").startswith("#"):
            in_nav = any(t == "nav" for t, _ in self._stack)
            (self.nav_links if in_nav else self.links).append(a["href"][1:])
        if tag == "table":
            divs = [x.get("class", "") for t, x in self._stack if t == "div"]
            self.table_parents.append(divs[-1] if divs else "")
        if tag == "details":
            self.details.append({"id": a.get("id"), "open": "open" in a, "rows": 0, "text": ""})
        if tag == "tr" and any(t == "details" for t, _ in self._stack):
            self.details[-1]["rows"] += 1
        if tag not in ("meta", "img", "br", "link"):
            self._stack.append((tag, a))

    def handle_endtag(self, tag):
        while self._stack:
            if self._stack.pop()[0] == tag:
                break

    def handle_data(self, data):
        if any(t == "details" for t, _ in self._stack):
            self.details[-1]["text"] += data


def _claims() -> list[Claim]:
    ne = "not enough seeds"
    return [
        Claim("above_ic3net", "Hierarchical above IC3Net", "s", "c", [
            Check("N = 40, p = 0.2", "supported", "diff 0.2 [0.1, 0.3]", "Welch t", "argmax"),
            Check("N = 40, p = 0.2", ne, "2 vs 3 seeds", "Welch t", "sample"),
            Check("N = 60, p = 0.2", ne, "2 vs 3 seeds", "Welch t", "argmax"),
            Check("N = 60, p = 0.2", ne, "2 vs 3 seeds", "Welch t", "sample"),
        ]),
        Claim("convergence", "Hierarchical training converges", "s", "c", [
            Check(f"N = {n}, p = 0.2", ne, "1 seed", "drift test", "training (sampled)") for n in (80, 90, 100)]),
    ]


def _page(wide_table: bool = False) -> str:
    claims = _claims()
    cells = pd.DataFrame({"cell_id": ["a"], "method": ["hierarchical"], "n_robots": [8], "loss_p": [0.2],
                          "seed": [0], "status": ["done"], "error": [""]})
    wide = pd.DataFrame([[f"a long cell value {i}-{j} " * 2 for j in range(30)] for i in range(60)],
                        columns=[f"column {j}" for j in range(30)])
    entries = [
        Entry("Summary of every configuration", ("summary.md",),
              tables=(("Summary", wide if wide_table else wide.iloc[:2, :3]),)),
    ]
    front = ClaimsFront(claims)
    paper = Part("The paper", [
        Entry("Fig. 1: training convergence", ("fig1.png",), ("a note",), image="fig1.png", caption="Fig. 1: x"),
        Entry("Claims of Sec. IV", ("claims.md",), html_block=front.checks_block(claims_frame(claims)))], front)
    return index_html(IndexData("results/x", {"grid": "smoke", "git_sha": "abc"}, cells, entries, [paper]))


def test_index_html__toc_links_land_on_every_heading_and_claim():
    page = _page()
    p = _Page()
    p.feed(page)
    assert len(p.ids) == len(set(p.ids)), "element ids must be unique"
    assert p.nav_links and set(p.nav_links) <= set(p.ids)  # every contents link has its target
    assert set(p.headings) <= set(p.nav_links)  # every section and entry is in the contents
    assert {"claim-above-ic3net", "claim-convergence"} <= set(p.nav_links)
    assert {d["id"] for d in p.details} == {"claim-above-ic3net", "claim-convergence"}
    assert set(p.links) <= set(p.ids)  # the verdict table links to each claim's block
    assert {"claim-above-ic3net", "claim-convergence"} <= set(p.links)


def test_index_html__undecided_checks_take_one_line_and_close_their_block():
    p = _Page()
    p.feed(_page())
    blocks = {d["id"]: d for d in p.details}
    ic3, conv = blocks["claim-above-ic3net"], blocks["claim-convergence"]
    assert ic3["open"] and ic3["rows"] == 1 + 1  # header + the one decided check
    assert "3 check(s): N = 40, p = 0.2 (sample); N = 60, p = 0.2 (argmax, sample)" in ic3["text"]
    assert "1 supported, 3 not enough seeds" in ic3["text"]
    assert not conv["open"] and conv["rows"] == 0
    assert "N = 80, p = 0.2 (training (sampled)); N = 90" in conv["text"]


def test_verdict_counts_and_undecided_text__by_hand():
    s = pd.Series(["not enough seeds", "supported", "contradicted", "supported"])
    assert verdict_counts(s) == "2 supported, 1 contradicted, 1 not enough seeds"
    rows = pd.DataFrame({"configuration": ["A", "A", "B"], "execution": ["argmax", "sample", "-"],
                         "scope": ["paper", "paper", "run"]})
    assert undecided_text(rows) == "A (argmax, sample); B [run]"


def test_index_html__every_table_scrolls_in_its_own_box_and_the_page_uses_the_window():
    page = _page(wide_table=True)
    p = _Page()
    p.feed(page)
    assert p.table_parents and all(c.split()[0] == "box" for c in p.table_parents), p.table_parents
    css = re.search(r"<style>(.*?)</style>", page, re.S).group(1)
    assert "max-width:60em" not in css.replace(" ", "")
    assert re.search(r"\.box\{[^}]*overflow:auto", css)


def _chromium() -> str | None:
    return next((shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)


def test_index_html__in_chromium_a_wide_table_scrolls_in_its_box_not_the_page(tmp_path):
    exe = _chromium()
    if exe is None:
        pytest.skip("no chromium on PATH: the layout is checked by its CSS only")
    probe = ("<script>const m=document.querySelector('main'),"
             "s=[...document.querySelectorAll('.box')].some(b=>b.scrollWidth>b.clientWidth);"
             "document.title=[document.documentElement.scrollWidth,window.innerWidth,"
             "Math.round(m.getBoundingClientRect().width),s].join(' ');</script>")
    (tmp_path / "index.html").write_text(_page(wide_table=True).replace("</body>", probe + "</body>"))
    res = subprocess.run([exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                          "--disable-component-update", "--disable-sync", "--no-first-run",
                          f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1400,1000", "--dump-dom",
                          (tmp_path / "index.html").as_uri()], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0
    page_w, win_w, main_w, box_scrolls = re.search(r"<title>(\d+) (\d+) (\d+) (\w+)</title>", res.stdout).groups()
    assert int(page_w) <= int(win_w)  # the wide table does not widen the page...
    assert box_scrolls == "true"  # ...it scrolls inside its box
    assert int(main_w) > 0.7 * int(win_w)  # the content uses the window, not a 60em column
