"""What a reviewer reads: captions under every figure (and in the files), one palette and
one label per method, no duplicated panel, ticks on measured N, Fig. 2's line and band from
one estimator, Table I's LaTeX (balanced, page-wide, n/a without a filter) and an index.html
whose tables are HTML tables with captions and whose links stay inside the report folder."""
from __future__ import annotations

import colorsys
import re
import shutil
import subprocess
from html.parser import HTMLParser

import numpy as np
import pandas as pd
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgb
from PIL import Image

from paper.figures.fig1_training import fig1_training
from paper.figures.fig2_success import GRID, fig2_success, seed_quantile_curves
from paper.figures.fig3_payload import fig3_payload
from paper.tables.table1_safety import table1_display, table1_frame, table1_latex
from reports.build import build_report
from reports.figures.plotting import method_color, method_label
from reports.stats import t_band
from tests.reports.synthetic import frames, joined, smoke_specs, write_store

BLUE = method_color("hierarchical")


def _two_seed_smoke() -> list[dict]:
    return [dict(s, seed=k) for k in (0, 1) for s in smoke_specs()]


@pytest.fixture(scope="module")
def paper():
    cells, train, evals = frames(seeds=2, episodes=40, eval_eps=8)
    return joined(cells, train), joined(cells, evals)


@pytest.fixture(scope="module")
def smoke():
    cells, train, evals = frames(episodes=30, eval_eps=6, specs=_two_seed_smoke())
    return joined(cells, train), joined(cells, evals)


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """``bench report`` on a 2-seed run of every method (smoke sizes)."""
    run = tmp_path_factory.mktemp("two_seed_smoke")
    write_store(run, *frames(episodes=30, eval_eps=6, specs=_two_seed_smoke()))
    return build_report(run)


def _lines(fig, label: str) -> list:
    return [ln for ax in fig.axes for ln in ax.get_lines() if ln.get_label() == label]


# ------------------------------------------------------------------ captions
@pytest.mark.parametrize("which", ["paper", "smoke"])
def test_figures__every_caption_names_configuration_seeds_episodes_and_band(which, request):
    train, evals = request.getfixturevalue(which)
    c1, c2, c3 = fig1_training(train).caption, fig2_success(evals).caption, fig3_payload(evals).caption
    assert "p = 0.2" in c1 and "2 seeds at N = " in c1 and "training episodes" in c1
    assert re.search(r"moving average over ([2-9]|\d\d+) episodes|not "
                     r"smoothed", c1) and "Student t interval over seeds" in c1
    assert "2 seeds at N = " in c2 and "evaluation episodes per seed" in c2 and "Thin lines: each seed" in c2
    assert "p = 0.2" in c3 and "IC3Net: 2 seeds at N =" in c3


def test_build__captions_in_html_sidecar_and_pdf_metadata(report):
    page = (report / "index.html").read_text()
    for stem in ("fig1_training", "fig2_success_percentiles", "fig3_comm_payload"):
        caption = (report / f"{stem}.txt").read_text().strip()
        assert caption.startswith("Fig. ")
        assert f"<figcaption>{caption[:40]}" in page.replace("&#x27;", "'")
        assert b"/Subject (" + caption.split("(")[0][:30].encode() in (report / f"{stem}.pdf").read_bytes()
        assert Image.open(report / f"{stem}.png").text["Description"] == caption
    # the leaderboard's, the learning curves' and the paper's three figures
    assert page.count("<figcaption>") == 5


# ------------------------------------------------------------------ palette, labels, panels
def test_figures__hierarchical_is_blue_and_labelled_ours_everywhere(paper, smoke):
    h, s, v = colorsys.rgb_to_hsv(*BLUE)
    assert 0.53 < h < 0.67 and s > 0.5  # the paper's method is blue
    for train, evals in (paper, smoke):
        for fig in (fig1_training(train).fig, fig2_success(evals).fig, fig3_payload(evals).fig):
            lines = _lines(fig, method_label("hierarchical"))
            assert lines and all(np.allclose(to_rgb(ln.get_color()), BLUE) for ln in lines)
            labels = {ln.get_label() for ax in fig.axes for ln in ax.get_lines()}
            assert "Hierarchical" not in labels  # never without "(ours)"
            for m in ("decentralized", "ic3net"):
                for ln in _lines(fig, method_label(m)):
                    assert np.allclose(to_rgb(ln.get_color()), method_color(m))


def test_fig1__panel_b_only_with_n80_to_100_and_in_shades_of_blue(paper, smoke):
    b_labels = ["N = 80", "N = 90", "N = 100"]
    fig = fig1_training(paper[0]).fig
    b_lines = [ln for lab in b_labels for ln in _lines(fig, lab)]
    assert len(b_lines) == 3
    hue = colorsys.rgb_to_hsv(*BLUE)[0]
    assert all(abs(colorsys.rgb_to_hsv(*to_rgb(ln.get_color()))[0] - hue) < 0.02 for ln in b_lines)
    built = fig1_training(smoke[0])
    assert len(built.fig.axes) == 2  # (a) at N = 4, 8 only: no (b) re-plotting them
    assert not any(_lines(built.fig, lab) for lab in b_labels)
    assert any("panel (b) is omitted" in n for n in built.notes)


def test_figures__axis_label_is_team_return_and_ticks_are_unique(paper):
    fig = fig1_training(paper[0]).fig
    FigureCanvasAgg(fig).draw()  # tick labels exist once drawn
    ylabels = {ax.get_ylabel() for ax in fig.axes} - {""}
    assert ylabels == {"team return"}
    for ax in fig.axes:
        texts = [t.get_text() for t in ax.get_xticklabels() if t.get_text()]
        assert len(texts) == len(set(texts))


def test_fig3__ticks_on_measured_n_and_ic3net_payload(paper, smoke):
    for _, evals in (paper, smoke):
        fig = fig3_payload(evals).fig
        measured = sorted(set(evals["n_robots"]))
        for ax in fig.axes:
            assert [int(t) for t in ax.get_xticks()] == measured
        (ic3,) = _lines(fig, "IC3Net")
        at_p = evals[(evals["method"] == "ic3net") & np.isclose(evals["loss_p"], 0.2)]
        want = at_p.groupby("n_robots")["payload_scalars_per_step"].mean()
        np.testing.assert_allclose(ic3.get_ydata(), want.to_numpy())


# ------------------------------------------------------------------ Fig. 2 estimator
def test_fig2__line_is_the_mean_of_seed_curves_and_lies_in_its_band():
    rng = np.random.default_rng(3)
    # two seeds with different episode counts: the pooled curve differs from the seed mean
    rows = pd.DataFrame({"cell_id": ["a"] * 5 + ["b"] * 40,
                         "success_rate": np.r_[rng.uniform(0.0, 0.3, 5), rng.uniform(0.6, 1.0, 40)]})
    curves = seed_quantile_curves(rows)
    mean, lo, hi = t_band(curves)
    np.testing.assert_allclose(mean, curves.mean(axis=0))
    assert np.all(lo <= mean + 1e-12) and np.all(mean <= hi + 1e-12)
    one = t_band(curves[:1])
    assert np.isnan(one[1]).all()


def test_fig2__plotted_line_is_the_seed_mean_on_the_grid(paper):
    _, evals = paper
    fig = fig2_success(evals).fig
    hier = evals[(evals["method"] == "hierarchical") & (evals["n_robots"] == 40) & np.isclose(evals["loss_p"], 0.2)]
    line = _lines(fig, method_label("hierarchical"))[0]
    np.testing.assert_allclose(line.get_xdata(), GRID)
    np.testing.assert_allclose(line.get_ydata(), 100 * seed_quantile_curves(hier).mean(axis=0))


# ------------------------------------------------------------------ Table I LaTeX
def _no_filter_frame(paper) -> pd.DataFrame:
    _, evals = paper
    ev = evals.copy()
    off = ev["n_robots"] == 40
    ev.loc[off, "safety_filter"] = False
    ev.loc[off & (ev["method"] == "hierarchical"), "correction_rate"] = 0.0
    return table1_frame(ev)[0]


def check_latex(tex: str) -> None:
    """Braces balance (escaped ones aside), every \\begin has its \\end, table* is used."""
    body = re.sub(r"\\[{}%&_#$]", "", tex)
    body = "\n".join(line.split("%", 1)[0] for line in body.splitlines())  # comments
    depth = 0
    for ch in body:
        depth += {"{": 1, "}": -1}.get(ch, 0)
        assert depth >= 0, "closing brace without an opening one"
    assert depth == 0, f"{depth} unclosed braces"
    stack = []
    for kind, env in re.findall(r"\\(begin|end)\{([^}]*)\}", body):
        if kind == "begin":
            stack.append(env)
        else:
            assert stack and stack.pop() == env, f"\\end{{{env}}} does not match"
    assert not stack, f"unclosed environments {stack}"
    assert r"\begin{table*}" in body


def test_table1_latex__parses_fits_and_says_na_without_a_filter(paper):
    frame = _no_filter_frame(paper)
    tex = table1_latex(frame)
    check_latex(tex)
    assert tex.count(r"\begin{tabular}{llrrrrrr}") == 1  # 8 short columns, CIs on their own row
    row40 = next(line for line in tex.splitlines() if line.startswith("40 & ours"))
    assert row40.split(" & ")[3:5] == ["n/a", "n/a"]
    disp = table1_display(frame, "argmax")
    assert "0.00" not in disp.loc[disp["N"] == "40", "Corr. (%)"].tolist()
    assert (disp.loc[disp["N"] == "60", "Corr. (%)"] != "n/a").all()


def test_check_latex__catches_an_unbalanced_brace_and_a_bad_end(paper):
    tex = table1_latex(_no_filter_frame(paper))
    with pytest.raises(AssertionError):
        check_latex(tex.replace(r"\caption{", r"\caption{{", 1))
    with pytest.raises(AssertionError):
        check_latex(tex.replace(r"\end{tabular}", r"\end{table}", 1))


def test_table1_latex__compiles_with_a_tex_engine(paper, tmp_path):
    engine = shutil.which("pdflatex") or shutil.which("tectonic")
    if engine is None:
        pytest.skip("neither pdflatex nor tectonic is on PATH: the .tex is only parsed")
    doc = ("\\documentclass[twocolumn]{article}\\usepackage{booktabs}\\begin{document}\n"
           + table1_latex(_no_filter_frame(paper)) + "\n\\end{document}\n")
    (tmp_path / "t.tex").write_text(doc)
    cmd = [engine, "-interaction=nonstopmode", "t.tex"] if engine.endswith("pdflatex") else [engine, "t.tex"]
    res = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stdout[-2000:]
    assert "Overfull \\hbox" not in res.stdout


# ------------------------------------------------------------------ index.html
class _Tables(HTMLParser):
    """Collects tables (first child caption?), caption texts, cell texts and links."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: list[dict] = []
        self.links: list[str] = []
        self._cap = False
        self._first = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table":
            self.tables.append({"caption": None, "cells": []})
            self._first = True
            return
        if tag in ("a", "img", "link", "script"):
            self.links += [v for k, v in a.items() if k in ("href", "src") and v]
        if self.tables and self._first:
            self._first = False
            if tag == "caption":
                self._cap = True
                self.tables[-1]["caption"] = ""

    def handle_endtag(self, tag):
        if tag == "caption":
            self._cap = False

    def handle_data(self, data):
        if self._cap:
            self.tables[-1]["caption"] += data
        elif self.tables:
            self.tables[-1]["cells"].append(data.strip())


def parse_index(page: str) -> _Tables:
    p = _Tables()
    p.feed(page)
    return p


def check_links(links: list[str]) -> None:
    for link in links:
        assert not re.match(r"^(/|[a-z]+:|\.\.)", link) and "/../" not in link, link


def test_index_html__every_table_is_an_html_table_with_a_caption(report):
    page = (report / "index.html").read_text()
    p = parse_index(page)
    assert all(t["caption"] for t in p.tables), [t["caption"] for t in p.tables]
    caps = " | ".join(t["caption"] for t in p.tables)
    for want in ("Table I (argmax)", "Summary of every configuration", "Claims of the paper", "manifest"):
        assert want in caps, want
    assert "Calibration of the claim tests" not in caps  # a run without its own calibration shows none
    claims = [t for t in p.tables if t["caption"].startswith("Claims of the paper")]
    checks = pd.read_csv(report / "claims.csv")
    assert set(checks["name"]) <= set(re.findall(r"<summary>([^<]*) <code>", page.replace("&#x27;", "'")))
    decided = checks[checks["verdict"] != "not enough seeds"]
    assert {f"Claims of the paper's Sec. IV: {n}: the checks that were decided" for n in decided["name"]} \
        == {t["caption"] for t in claims}  # readable names, a table per claim with a decided check
    cells = {c for t in claims for c in t["cells"]}
    assert set(decided["numbers"].astype(str)) <= cells and any(re.search(r"\d", c) for c in cells)
    summary = [c for t in p.tables if t["caption"].startswith("Summary") for c in t["cells"]]  # split in two
    assert "n/a" in summary and "pibt" in summary
    assert "|" not in " ".join(summary)  # not Markdown
    check_links(p.links)


def test_check_links__catches_absolute_and_parent_links():
    for bad in ("/tmp/run/report/x.png", "../replays/a.gif", "../../studies/s/study.html", "file:///x"):
        with pytest.raises(AssertionError):
            check_links([bad])
    check_links(["fig1_training.png", "studies/demo/study.html", "replays/a.gif"])


def test_index_html__survives_copying_the_report_folder(report, tmp_path):
    copy = tmp_path / "elsewhere"
    shutil.copytree(report, copy)
    for link in parse_index((copy / "index.html").read_text()).links:
        if not link.startswith("#"):  # in-page anchors: tests/reports/test_referee_page.py
            assert (copy / link).exists(), link


def test_index_html__renders_in_headless_chromium(report, tmp_path):
    exe = next((shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)
    if exe is None:
        pytest.skip("no chromium on PATH: the HTML is checked with html.parser only")
    res = subprocess.run([exe, "--headless", "--no-sandbox", "--disable-gpu", "--dump-dom",
                          (report / "index.html").as_uri()], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0
    p = parse_index(res.stdout)
    assert len(p.tables) >= 5 and all(t["caption"] for t in p.tables)
