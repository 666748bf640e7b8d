"""The generic report comes first for any run (SPEC 5): a run of outside methods only gets the
leaderboard first, the learning curves of its learned methods and the robustness of
training, and no section of the paper's wing; a run with one of the paper's methods gets the
wing's section after the generic entries."""
from __future__ import annotations

import re
from pathlib import Path

import pandas as pd
import pytest

from bench.design.cells import Cell
from bench.design.grids import Grid
from paper.sections import TITLE
from reports.build import build_report
from reports.figures.plotting import method_label
from tests.bench.conftest import toy_spec, write_finished_store
from tests.bench.toy_method import TOY_PATH


def _cells(method: str) -> list[Cell]:
    spec = toy_spec() if method == TOY_PATH else {**toy_spec(), "episodes": 0}
    return [Cell.make(**{**spec, "method": method, "seed": s}) for s in range(2)]


@pytest.fixture(scope="module")
def outside(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = tmp_path_factory.mktemp("outside") / "run"
    write_finished_store(run, Grid("outside", "an outside method only", tuple(_cells(TOY_PATH))))
    return build_report(run)


def _headings(md: str, level: str) -> list[str]:
    return re.findall(rf"^{level} (.+)$", md, flags=re.M)


def test_outside_run__leaderboard_first_then_learning_curves_and_no_paper_section(outside: Path) -> None:
    md = (outside / "index.md").read_text(encoding="utf-8")
    entries = _headings(md, "###")
    assert entries[:3] == ["Leaderboard: every method of the run", "Learning curves: every learned method of the run",
                           "Robustness of training"]
    assert TITLE not in md and "Claims of the paper" not in md and "Fig. 1" not in md
    for absent in ("claims.md", "fig1_training.png", "table1_safety.md", "fig3_comm_payload.png"):
        assert not (outside / absent).exists(), absent
    html = (outside / "index.html").read_text(encoding="utf-8")
    assert TITLE not in html and html.index("Leaderboard: every method") < html.index("Learning curves")


def test_outside_run__the_learned_methods_curve_and_its_robustness_row(outside: Path) -> None:
    caption = (outside / "learning_curves.txt").read_text(encoding="utf-8")
    assert f"every learned method of the run ({method_label(TOY_PATH)})" in caption
    assert (outside / "learning_curves.png").stat().st_size > 0
    rows = pd.read_csv(outside / "robustness.csv")
    assert rows["method"].tolist() == [TOY_PATH] and rows["seeds"].tolist() == [2]


def test_run_with_a_paper_method__the_paper_section_follows_the_generic_entries(tmp_path: Path) -> None:
    run = tmp_path / "run"
    write_finished_store(run, Grid("mixed", "toy and PIBT", tuple(_cells(TOY_PATH) + _cells("pibt"))))
    md = (build_report(run) / "index.md").read_text(encoding="utf-8")
    sections = _headings(md, "##")
    assert sections.index("Figures and tables") < sections.index(TITLE)
    assert md.index("### Leaderboard") < md.index(f"## {TITLE}") < md.index("### Claims of Sec. IV")
    assert "Fig. 1: training convergence" not in md  # the run trained neither method Fig. 1 draws
