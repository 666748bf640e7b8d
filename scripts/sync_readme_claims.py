"""Copy the committed reproduction's tables into docs/reproduction.md and the README.

    .venv/bin/python scripts/sync_readme_claims.py [reproduction/paper]

Replaces the text between ``<!-- NAME:begin -->`` and ``<!-- NAME:end -->``:

* in ``docs/reproduction.md``: ``claims_table`` with ``<run>/report/claims_table.md``,
  ``progress`` with ``<run>/report/progress.md`` and ``success`` with
  ``<run>/report/success_by_mode.md`` (all written by ``bench report``), verbatim;
* in ``README.md``: ``verdicts`` with the count of each verdict per claim in
  ``claims_table.md`` and ``pooled`` with its pooled sign tests, and, once the full grid has
  a report, ``full_leaders`` with the rows of the "Per method" table of
  ``reproduction/full/report/leaders.md`` in the modes of ``FULL_MODES`` and
  ``full_ordering`` with its sign tests of the ordering across configurations.

So no verdict, success rate or status on either page is typed by hand; ``tests/reproduction``
checks that both pages agree with the committed report.
"""
from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BLOCKS = {"claims_table": "claims_table.md", "progress": "progress.md",  # page marker -> report file
          "success": "success_by_mode.md"}
PAGE = "docs/reproduction.md"  # where BLOCKS go, verbatim
README = "README.md"
FULL = ROOT / "reproduction" / "full"  # the full grid, whose leaders.md gives the README's full_leaders
FULL_MODES = ("| argmax |", "| sample |")  # its per-method rows the README shows


def markers(name: str) -> tuple[str, str]:
    return f"<!-- {name}:begin -->", f"<!-- {name}:end -->"


def readme_block(text: str, name: str = "claims_table") -> str:
    """The page's block ``name`` (between its markers); ValueError without them."""
    begin, end = markers(name)
    if begin not in text or end not in text:
        raise ValueError(f"no {begin} ... {end} block")
    return text.split(begin, 1)[1].split(end, 1)[0].strip("\n") + "\n"


def verdicts(claims_table: str) -> str:
    """One row per claim of ``claims_table.md``: how many of its checks got each verdict."""
    counts: dict[str, Counter[str]] = {}
    claim = ""
    lines = claims_table.splitlines()
    header = [c.strip() for c in lines[0].strip().strip("|").split("|")]
    col = header.index("verdict")
    for line in lines[2:]:
        if not line.startswith("|"):
            break  # the checks' table ends; the pooled tests follow (``pooled``)
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        claim = cells[0].strip("*") or claim
        counts.setdefault(claim, Counter())[cells[col].strip("*")] += 1
    rows = ["| claim | checks | verdicts |", "|---|---|---|"]
    for claim, c in counts.items():
        rows.append(f"| {claim} | {sum(c.values())} | "
                    + ", ".join(f"{v} {k}" for k, v in c.most_common()) + " |")
    return "\n".join(rows) + "\n"


def pooled(claims_table: str) -> str:
    """The pooled sign tests of ``claims_table.md`` (the table after its checks), with their
    one-line heading."""
    marker = "Pooled across configurations"
    if marker not in claims_table:
        return "No claim has a pooled test yet.\n"
    part = claims_table[claims_table.index(marker):]
    return "\n".join(ln for ln in part.splitlines() if ln.startswith((marker, "|"))) + "\n"


def ordering(leaders: str) -> str:
    """The table of leaders.md's "Ordering across configurations" section (sign tests)."""
    from reports.tables.ordering import ORDERING_HEADING

    section = leaders.split(ORDERING_HEADING, 1)[1]
    return "\n".join(ln for ln in section.splitlines() if ln.startswith("|")) + "\n"


def per_method(leaders: str) -> str:
    """The header and the ``FULL_MODES`` rows of leaders.md's "Per method" table."""
    from reports.tables.leaders import PER_METHOD_HEADING

    section = leaders.split(f"\n{PER_METHOD_HEADING}\n", 1)[1].split("\n## ", 1)[0]
    table = [ln for ln in section.splitlines() if ln.startswith("|")]
    return "\n".join(table[:2] + [ln for ln in table[2:] if ln.startswith(FULL_MODES)]) + "\n"


def expected_blocks(run: Path, full: Path = FULL) -> dict[str, dict[str, str]]:
    """page (relative to the repository) -> marker name -> the text its block must hold
    (``full_leaders`` only once ``full`` has a report)."""
    report = {name: (run / "report" / file).read_text(encoding="utf-8") for name, file in BLOCKS.items()}
    readme = {"verdicts": verdicts(report["claims_table"]), "pooled": pooled(report["claims_table"])}
    if (full / "report" / "leaders.md").is_file():
        leaders = (full / "report" / "leaders.md").read_text(encoding="utf-8")
        readme["full_leaders"] = per_method(leaders)
        readme["full_ordering"] = ordering(leaders)
    return {PAGE: report, README: readme}


def main() -> int:
    run = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "reproduction" / "paper"
    for page, blocks in expected_blocks(run).items():
        path = ROOT / page
        text = path.read_text(encoding="utf-8")
        for name, table in blocks.items():
            readme_block(text, name)  # the markers exist
            begin, end = markers(name)
            head, rest = text.split(begin, 1)
            text = f"{head}{begin}\n{table}{end}{rest.split(end, 1)[1]}"
            print(f"{page}: {name} from {(FULL if name == 'full_leaders' else run) / 'report'}")
        path.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
