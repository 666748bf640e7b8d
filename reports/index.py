"""The report's front page, ``index.md`` and ``index.html``: every output, its notes, the
claims' verdicts, what the run lacks (cells not done, failed with their error, paper
configurations absent) and the run's manifest (versions, git commit, command)."""
from __future__ import annotations

import html
import json
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from reports.claims import Claim


@dataclass(frozen=True)
class Entry:
    """One output of the report: a title, its files (first = main view) and notes."""

    title: str
    files: tuple[str, ...]
    notes: tuple[str, ...] = ()
    image: str | None = None  # PNG shown inline in the HTML page


@dataclass
class IndexData:
    run_dir: str
    manifest: dict[str, Any]
    cells: pd.DataFrame  # all cells of the store
    entries: list[Entry]
    claims: list[Claim]
    problems: list[str] = field(default_factory=list)
    replays: list[str] = field(default_factory=list)


def _manifest_rows(manifest: dict[str, Any]) -> list[tuple[str, str]]:
    rows = []
    for k, v in manifest.items():
        if isinstance(v, dict):
            rows += [(f"{k}.{kk}", vv if isinstance(vv, str) else json.dumps(vv)) for kk, vv in v.items()]
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for i, item in enumerate(v):  # e.g. one entry per (resumed) invocation
                for kk, vv in item.items():
                    text = " ".join(map(str, vv)) if isinstance(vv, list) else str(vv)
                    rows.append((f"{k}[{i}].{kk}", text))
        elif isinstance(v, list):
            rows.append((k, " ".join(map(str, v))))
        else:
            rows.append((k, str(v)))
    return rows


def _cell_lines(cells: pd.DataFrame) -> tuple[str, list[dict[str, str]]]:
    counts = cells["status"].value_counts()
    head = f"{len(cells)} cells: " + ", ".join(f"{int(c)} {s}" for s, c in counts.items())
    rows = []
    for _, r in cells[cells["status"] != "done"].sort_values(["status", "method", "n_robots"]).iterrows():
        err = str(r.get("error", "") or "")
        rows.append({"cell": str(r["cell_id"]), "method": str(r["method"]), "N": str(r["n_robots"]),
                     "p": f"{float(r['loss_p']):g}", "seed": str(r["seed"]), "status": str(r["status"]),
                     "error": err.splitlines()[-1][:160] if err else ""})
    return head, rows


def index_markdown(d: IndexData) -> str:
    title = d.manifest.get("grid", "run")
    lines = [f"# Report: {title}", "", f"Run directory: `{d.run_dir}`", ""]
    head, missing = _cell_lines(d.cells)
    lines += ["## Claims of the paper (Sec. IV)", "", "| claim | verdict |", "|---|---|"]
    lines += [f"| {c.key} | **{c.verdict}** |" for c in d.claims]
    lines += ["", "Details, numbers and tests: [claims.md](claims.md)", "", "## Figures and tables", ""]
    for e in d.entries:
        links = ", ".join(f"[{f}]({f})" for f in e.files)
        lines.append(f"### {e.title}\n\n{links}\n")
        if e.image:
            lines.append(f"![{e.title}]({e.image})\n")
        lines += [f"- {n}" for n in e.notes]
        if e.notes:
            lines.append("")
    if d.replays:
        lines += ["## Replays", ""] + [f"- [{r}]({r})" for r in d.replays] + [""]
    lines += ["## What this run lacks", "", head, ""]
    if missing:
        lines += ["| cell | method | N | p | seed | status | error |", "|---|---|---|---|---|---|---|"]
        lines += ["| " + " | ".join(r[k].replace("|", "\\|") for k in
                                   ("cell", "method", "N", "p", "seed", "status", "error")) + " |"
                  for r in missing]
        lines.append("")
    else:
        lines.append("Every cell of the store is done.\n")
    lines += [f"- {p}" for p in d.problems]
    lines += ["", "## Manifest", "", "| key | value |", "|---|---|"]
    lines += [f"| {k} | `{v}` |" for k, v in _manifest_rows(d.manifest)]
    if not d.manifest:
        lines.append("| (no manifest.json) | |")
    return "\n".join(lines) + "\n"


def _table(head: list[str], rows: list[list[str]]) -> str:
    h = "".join(f"<th>{html.escape(c)}</th>" for c in head)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>"


_CSS = """body{font-family:system-ui,sans-serif;max-width:60em;margin:2em auto;padding:0 1em;
line-height:1.4}table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;
padding:2px 6px;font-size:90%;vertical-align:top}img{max-width:100%;border:1px solid #eee}
.supported{color:#1a7f37}.contradicted{color:#b42318}.inconclusive{color:#555}
.not-enough-seeds{color:#8a6d00}.verified-by-construction{color:#1a5f7f}
code{font-size:90%}"""


def index_html(d: IndexData) -> str:
    e = html.escape
    title = e(str(d.manifest.get("grid", "run")))
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>Report: {title}</title>"
             f"<style>{_CSS}</style></head><body><h1>Report: {title}</h1>",
             f"<p>Run directory: <code>{e(d.run_dir)}</code></p>", "<h2>Claims of the paper (Sec. IV)</h2>"]
    parts.append(_table(["claim", "verdict"], [
        [e(c.key), f"<b class='{c.verdict.replace(' ', '-')}'>{e(c.verdict)}</b>"] for c in d.claims]))
    parts.append("<p>Details, numbers and tests: <a href='claims.md'>claims.md</a></p>")
    parts.append("<h2>Figures and tables</h2>")
    for en in d.entries:
        links = ", ".join(f"<a href='{e(f)}'>{e(f)}</a>" for f in en.files)
        parts.append(f"<h3>{e(en.title)}</h3><p>{links}</p>")
        if en.image:
            parts.append(f"<img src='{e(en.image)}' alt='{e(en.title)}' width='700'>")
        if en.notes:
            parts.append("<ul>" + "".join(f"<li>{e(n)}</li>" for n in en.notes) + "</ul>")
    if d.replays:
        parts.append("<h2>Replays</h2><ul>" + "".join(
            f"<li><a href='{e(r)}'>{e(r)}</a></li>" for r in d.replays) + "</ul>")
    head, missing = _cell_lines(d.cells)
    parts.append(f"<h2>What this run lacks</h2><p>{e(head)}</p>")
    if missing:
        keys = ["cell", "method", "N", "p", "seed", "status", "error"]
        parts.append(_table(keys, [[e(r[k]) for k in keys] for r in missing]))
    else:
        parts.append("<p>Every cell of the store is done.</p>")
    if d.problems:
        parts.append("<ul>" + "".join(f"<li>{e(p)}</li>" for p in d.problems) + "</ul>")
    parts.append("<h2>Manifest</h2>")
    rows = [[e(k), f"<code>{e(v)}</code>"] for k, v in _manifest_rows(d.manifest)]
    parts.append(_table(["key", "value"], rows or [["(no manifest.json)", ""]]))
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"
