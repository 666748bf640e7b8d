"""MkDocs hooks (mkdocs.yml `hooks:`): pages and files the site takes from outside docs/.

* ``cli.md``: the CLI reference, generated from the Typer app at build time with Typer's
  own generator (``python -m typer bench.cli utils docs``), so it cannot drift from
  ``bench --help``.
* ``changelog.md``: the repository's ``CHANGELOG.md``, as it is.
* ``reproduction/<run>/report/...``: every committed report's figures and tables, at the paths
  the README and ``docs/reproduction.md`` link them by, so those links resolve in the site
  (``mkdocs build --strict`` fails on a link to a missing file).
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]
# Every committed report (paper, ablation, and the full grid once it is reported); a page that
# links a report missing here still fails the strict build.
REPORTS = sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "reproduction").glob("*/report") if p.is_dir())


def cli_reference() -> str:
    """The Markdown reference of every `bench` command (Typer's `utils docs`)."""
    out = subprocess.run(
        [sys.executable, "-m", "typer", "bench.cli", "utils", "docs", "--name", "bench",
         "--title", "CLI reference"],
        cwd=ROOT, capture_output=True, text=True, check=True,
    ).stdout
    intro = ("Generated from the Typer app when the site is built (`bench COMMAND --help` "
             "prints the same). Guides: [the user guide](guide/run.md).\n\n")
    head, rest = out.split("\n", 1)
    return f"{head}\n\n{intro}{_escape_angles(rest)}"


def _escape_angles(text: str) -> str:
    """``<`` and ``>`` outside code as entities: help text such as ``results/<grid>`` would
    otherwise be read as an HTML tag and vanish from the page."""
    out, fenced = [], False
    for line in text.splitlines(keepends=True):
        if line.startswith("```"):
            fenced = not fenced
        if not fenced and not line.startswith("```"):
            parts = line.split("`")
            parts[::2] = [p.replace("<", "&lt;").replace(">", "&gt;") for p in parts[::2]]
            line = "`".join(parts)
        out.append(line)
    return "".join(out)


def on_files(files: Files, config) -> Files:
    files.append(File.generated(config, "cli.md", content=cli_reference()))
    files.append(File.generated(config, "changelog.md",
                                content=(ROOT / "CHANGELOG.md").read_text(encoding="utf-8")))
    for folder in REPORTS:
        for path in sorted((ROOT / folder).iterdir()):
            if path.is_file():
                files.append(File(f"{folder}/{path.name}", src_dir=str(ROOT),
                                  dest_dir=config["site_dir"],
                                  use_directory_urls=config["use_directory_urls"]))
    return files
