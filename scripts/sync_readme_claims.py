"""Copy the committed reproduction's tables into docs/reproduction.md and the README.

    .venv/bin/python scripts/sync_readme_claims.py [reproduction/paper]

Replaces the text between ``<!-- NAME:begin -->`` and ``<!-- NAME:end -->``:

* in ``docs/reproduction.md``: ``claims_table`` with ``<run>/report/claims_table.md``,
  ``progress`` with ``<run>/report/progress.md`` and ``success`` with
  ``<run>/report/success_by_mode.md`` (all written by ``bench report``), verbatim;
* in ``README.md``: ``verdicts`` with the count of each verdict per claim in
  ``claims_table.md`` and its pooled sign test, and, once the full grid has a report,
  ``full_ordering`` with the rows of the sign tests of the ordering across configurations
  of ``reproduction/full/report/leaders.md`` (``ORDERING_HEADING``) in the modes of
  ``FULL_MODES``.

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
FULL = ROOT / "reproduction" / "full"  # the full grid, whose leaders.md gives the README's full_ordering
FULL_MODES = ("| argmax |", "| sample |")  # the modes of its rows the README shows


def markers(name: str) -> tuple[str, str]:
    return f"<!-- {name}:begin -->", f"<!-- {name}:end -->"


def readme_block(text: str, name: str = "claims_table") -> str:
    """The page's block ``name`` (between its markers); ValueError without them."""
    begin, end = markers(name)
    if begin not in text or end not in text:
        raise ValueError(f"no {begin} ... {end} block")
    return text.split(begin, 1)[1].split(end, 1)[0].strip("\n") + "\n"


def pooled(claims_table: str) -> dict[str, str]:
    """Claim name -> its pooled sign test, from the table after the checks of ``claims_table.md``."""
    marker = "Pooled across configurations"
    if marker not in claims_table:
        return {}
    rows = [ln for ln in claims_table.split(marker, 1)[1].splitlines() if ln.startswith("|")][2:]
    cells = [[c.strip() for c in ln.strip().strip("|").split("|")] for ln in rows]
    return {c[0]: c[1] for c in cells if len(c) >= 2}


def verdicts(claims_table: str) -> str:
    """One row per claim of ``claims_table.md``: how many of its checks got each verdict, and
    its pooled sign test across them."""
    counts: dict[str, Counter[str]] = {}
    claim = ""
    lines = claims_table.splitlines()
    header = [c.strip() for c in lines[0].strip().strip("|").split("|")]
    col = header.index("verdict")
    for line in lines[2:]:
        if not line.startswith("|"):
            break  # the checks' table ends; the pooled tests follow
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        claim = cells[0].strip("*") or claim
        counts.setdefault(claim, Counter())[cells[col].strip("*")] += 1
    tests = pooled(claims_table)
    rows = ["| claim | checks | verdicts | pooled sign test |", "|---|---|---|---|"]
    for claim, c in counts.items():
        rows.append(f"| {claim} | {sum(c.values())} | "
                    + ", ".join(f"{v} {k}" for k, v in c.most_common()) + f" | {tests.get(claim, '-')} |")
    return "\n".join(rows) + "\n"


def ordering(leaders: str) -> str:
    """The header and the ``FULL_MODES`` rows of leaders.md's "Ordering across configurations" table."""
    from reports.tables.ordering import ORDERING_HEADING

    table = [ln for ln in leaders.split(ORDERING_HEADING, 1)[1].splitlines() if ln.startswith("|")]
    return "\n".join(table[:2] + [ln for ln in table[2:] if ln.startswith(FULL_MODES)]) + "\n"


def expected_blocks(run: Path, full: Path = FULL) -> dict[str, dict[str, str]]:
    """page (relative to the repository) -> marker name -> the text its block must hold
    (``full_leaders`` only once ``full`` has a report)."""
    report = {name: (run / "report" / file).read_text(encoding="utf-8") for name, file in BLOCKS.items()}
    readme = {"verdicts": verdicts(report["claims_table"])}
    if (full / "report" / "leaders.md").is_file():
        readme["full_ordering"] = ordering((full / "report" / "leaders.md").read_text(encoding="utf-8"))
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
            print(f"{page}: {name} from {(FULL if name.startswith('full_') else run) / 'report'}")
        path.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
