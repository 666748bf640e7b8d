"""Copy the committed reproduction's claims table into the README (issue 13).

    .venv/bin/python scripts/sync_readme_claims.py [reproduction/paper]

Replaces the text between ``<!-- claims_table:begin -->`` and ``<!-- claims_table:end -->``
in README.md with ``<run>/report/claims_table.md`` (written by ``bench report``), so the
README's verdicts are the committed report's; ``tests/reproduction`` checks they agree.
"""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BEGIN, END = "<!-- claims_table:begin -->", "<!-- claims_table:end -->"


def readme_block(text: str) -> str:
    """The README's claims table (between the markers); ValueError without them."""
    if BEGIN not in text or END not in text:
        raise ValueError(f"README.md has no {BEGIN} ... {END} block")
    return text.split(BEGIN, 1)[1].split(END, 1)[0].strip("\n") + "\n"


def main() -> int:
    run = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "reproduction" / "paper"
    table = (run / "report" / "claims_table.md").read_text(encoding="utf-8")
    readme = ROOT / "README.md"
    text = readme.read_text(encoding="utf-8")
    readme_block(text)  # the markers exist
    head, rest = text.split(BEGIN, 1)
    tail = rest.split(END, 1)[1]
    readme.write_text(f"{head}{BEGIN}\n{table}{END}{tail}", encoding="utf-8")
    print(f"README.md: claims table from {run / 'report' / 'claims_table.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
