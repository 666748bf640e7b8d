"""Copy the committed reproduction's claims, success and status tables into the README (issue 13).

    .venv/bin/python scripts/sync_readme_claims.py [reproduction/paper]

Replaces the text between ``<!-- claims_table:begin -->`` and ``<!-- claims_table:end -->``
in README.md with ``<run>/report/claims_table.md``, between ``<!-- progress:begin -->``
and ``<!-- progress:end -->`` with ``<run>/report/progress.md``, and between
``<!-- success:begin -->`` and ``<!-- success:end -->`` with
``<run>/report/success_by_mode.md`` (all written by ``bench report``), so the README's
verdicts, success rates and status are the committed report's; ``tests/reproduction``
checks they agree.
"""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BLOCKS = {"claims_table": "claims_table.md", "progress": "progress.md",  # README marker -> report file
          "success": "success_by_mode.md"}


def markers(name: str) -> tuple[str, str]:
    return f"<!-- {name}:begin -->", f"<!-- {name}:end -->"


def readme_block(text: str, name: str = "claims_table") -> str:
    """The README's block ``name`` (between its markers); ValueError without them."""
    begin, end = markers(name)
    if begin not in text or end not in text:
        raise ValueError(f"README.md has no {begin} ... {end} block")
    return text.split(begin, 1)[1].split(end, 1)[0].strip("\n") + "\n"


def main() -> int:
    run = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "reproduction" / "paper"
    readme = ROOT / "README.md"
    text = readme.read_text(encoding="utf-8")
    for name, file in BLOCKS.items():
        table = (run / "report" / file).read_text(encoding="utf-8")
        readme_block(text, name)  # the markers exist
        begin, end = markers(name)
        head, rest = text.split(begin, 1)
        text = f"{head}{begin}\n{table}{end}{rest.split(end, 1)[1]}"
        print(f"README.md: {name} from {run / 'report' / file}")
    readme.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
