"""The report read at 1400 px (issue 51, item 5): no legend is cut at its figure's edge,
figures are shown at their natural size up to the column's width and link to the
full-size image, and a smoke report's tables fit the column instead of scrolling sideways.

The legend of the smoke report's success_vs_n was four columns wide in a 3.5 in figure, so
its ends were cut ("PI" of PIBT). The figures are checked twice: ``fitted_legend`` by
itself, and every PNG of a smoke-sized report for ink on its outermost pixels (a clipped
legend leaves some; constrained layout leaves a white margin otherwise). The page is
rendered in headless Chromium at 1400 px, which the test skips, saying so, when no
chromium is installed (``apt-get install chromium``)."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure
from PIL import Image

from reports.build import build_report
from reports.figures.plotting import fitted_legend, new_figure, paper_style
from tests.reports.synthetic import frames, smoke_specs, write_store

LONG = ["Hierarchical (ours)", "Decentralized", "IC3Net", "PIBT"]


@pytest.fixture(scope="module")
def smoke_report(tmp_path_factory) -> Path:
    """``bench report`` of a one-seed run of every method at N = 8, 16, the smoke grid's
    shape, at three p so that success_vs_n has three panels: 7 in, wider than the column."""
    run = tmp_path_factory.mktemp("smoke_1400")
    specs = [s for p in (0.2, 0.4, 0.6) for s in smoke_specs(ns=(8, 16), p=p)]
    write_store(run, *frames(episodes=16, eval_eps=4, specs=specs))
    return build_report(run)


def _legend_figure(labels: list[str], width_in: float) -> tuple[Figure, int]:
    with paper_style():
        fig = new_figure(2.0, width_in)
        ax = fig.add_subplot()
        for k, lab in enumerate(labels):
            ax.plot([0, 1], [k, k], label=lab)
        legend = fitted_legend(fig, *ax.get_legend_handles_labels(), "outside lower center")
        fig.draw_without_rendering()
        box = legend.get_window_extent()
        assert 0 <= box.x0 and box.x1 <= fig.bbox.width, (box, fig.bbox)
        columns = len({round(t.get_window_extent().x0) for t in legend.get_texts()})
    return fig, columns


def test_fitted_legend__drops_columns_only_when_a_row_is_wider_than_the_figure():
    _, ncol = _legend_figure(LONG, 3.5)
    assert ncol < 4  # four labels in a row are wider than a paper column...
    _, ncol = _legend_figure(LONG, 7.0)
    assert ncol == 4  # ...but fit a two-column figure, which keeps its row
    _, ncol = _legend_figure(["a", "b"], 3.5)
    assert ncol == 2


def _ink_on_edges(png: Path) -> dict[str, int]:
    """Dark pixels (grey < 200) on each outermost row and column of ``png``."""
    a = np.asarray(Image.open(png).convert("L"))
    edges = {"left": a[:, 0], "right": a[:, -1], "top": a[0], "bottom": a[-1]}
    return {k: int((v < 200).sum()) for k, v in edges.items() if (v < 200).any()}


def test_smoke_report__no_figure_is_cut_at_its_edges(smoke_report):
    pngs = sorted(smoke_report.glob("*.png"))
    assert any(p.name == "success_vs_n.png" for p in pngs)
    cut = {p.name: e for p in pngs if (e := _ink_on_edges(p))}
    assert not cut, f"ink on the outermost pixels (a clipped legend or label): {cut}"


def _chromium() -> str | None:
    return next((shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)


# Runs once the images are loaded: per <img> its natural width, its rendered box, whether a
# link to its own file wraps it; the column's content box; the page's and the window's
# widths; the table boxes that scroll sideways (widths and caption). Written into the title, read from --dump-dom.
PROBE = """<script>addEventListener('load',()=>{const m=document.querySelector('main'),
cs=getComputedStyle(m),mr=m.getBoundingClientRect(),
left=mr.left+parseFloat(cs.paddingLeft),right=mr.right-parseFloat(cs.paddingRight);
const imgs=[...document.querySelectorAll('main img')].map(i=>{const r=i.getBoundingClientRect(),
a=i.closest('a');return [i.getAttribute('src'),i.naturalWidth,Math.round(r.left),Math.round(r.right),
Math.round(r.width),a?a.getAttribute('href'):''].join(',')});
const wide=[...document.querySelectorAll('.box')].filter(b=>b.scrollWidth>b.clientWidth+1)
.map(b=>[b.scrollWidth,b.clientWidth,(b.querySelector('caption')||{}).textContent]);
document.title=JSON.stringify({left:Math.floor(left),right:Math.ceil(right),page:document.documentElement.scrollWidth,
win:innerWidth,wide:wide,imgs:imgs});});</script>"""


def test_smoke_report__at_1400px_figures_fit_the_column_and_tables_do_not_scroll(smoke_report, tmp_path):
    exe = _chromium()
    if exe is None:
        pytest.skip("no chromium on PATH (apt-get install chromium): the page at 1400 px is not rendered")
    page = smoke_report / "index.html"
    page.write_text(page.read_text().replace("</body>", PROBE + "</body>"))
    res = subprocess.run([exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                          "--disable-component-update", "--disable-sync", "--no-first-run", "--hide-scrollbars",
                          f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1400,1000", "--dump-dom",
                          page.as_uri()], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    title = re.search(r"<title>(\{.*\})</title>", res.stdout)
    assert title, "the probe did not run"
    got = json.loads(title.group(1).replace("&quot;", '"'))
    assert got["win"] == 1400 and got["page"] <= got["win"]  # nothing widens the page
    assert not got["wide"], f"tables of the smoke report scroll sideways in their box: {got['wide']}"
    column = got["right"] - got["left"]
    assert len(got["imgs"]) >= 5
    assert any(int(row.split(",")[1]) > column for row in got["imgs"])  # a figure wider than the column
    for row in got["imgs"]:
        src, natural, x0, x1, width, href = row.split(",")
        assert int(natural) > 0, f"{src} did not load"
        assert got["left"] <= int(x0) and int(x1) <= got["right"], f"{src} leaves the column: {row}"
        assert abs(int(width) - min(int(natural), column)) <= 2, f"{src} not at natural or column width: {row}"
        assert href == src, f"{src} does not link to its full-size image"
