"""The report's front page, ``index.md`` and ``index.html``: every output and its notes, the
generic entries first and then each registered section (``reports.sections``) under its
own heading with its front matter (e.g. a section's verdicts of its claims), what the run
lacks (cells not done, failed with their error) and the run's manifest (versions, git
commit, command).

In ``index.html`` a table of contents (``reports.pages.layout``) links every section and
entry; the content uses the window's width; every figure is shown at its natural size up
to the column's width, links to its full-size image and has its caption beside or under
it; every table is an HTML table with a caption, written by pandas' ``Styler.to_html``
with every cell escaped, its cells wrapping to fit the column, in a box that scrolls only
when the table is still wider, or longer than the box. An entry may add its own HTML
block (``Entry.html_block``, e.g. a section's checks grouped per claim). Every link is
relative to the report folder and stays inside it (no ``..``), so a copied report folder
keeps working."""
from __future__ import annotations

import html
import json
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import pandas as pd

from reports.pages.layout import PAGE_CSS, Anchors, html_table, scroll_box, toc_html
from reports.pages.provenance import provenance_lines

TocItems = list[tuple[str, str]]  # (text, element id) under one heading of the table of contents


@dataclass(frozen=True)
class Entry:
    """One output of the report: a title, its files (first = main view) and notes."""

    title: str
    files: tuple[str, ...]
    notes: tuple[str, ...] = ()
    image: str | None = None  # PNG shown inline in the HTML page
    caption: str = ""  # printed under the figure (index.html, index.md)
    tables: tuple[tuple[str, pd.DataFrame], ...] = ()  # (caption, display strings) -> HTML tables
    # HTML the entry adds under its files (given the page's anchors and its heading's
    # table-of-contents items, which it may extend), e.g. a section's checks grouped per claim
    html_block: Callable[[Anchors, TocItems], str] | None = None


class Front(Protocol):
    """What a section prints under its heading before its entries (index.md and index.html)."""

    def markdown(self) -> list[str]: ...

    def html(self, anchor: Anchors, toc: TocItems) -> list[str]: ...


@dataclass(frozen=True)
class Part:
    """A registered section of the index (reports.sections): heading, front matter, entries."""

    title: str
    entries: list[Entry]
    front: Front | None = None


@dataclass
class IndexData:
    run_dir: str
    manifest: dict[str, Any]
    cells: pd.DataFrame  # all cells of the store
    entries: list[Entry]  # the generic report's
    parts: list[Part] = field(default_factory=list)  # registered sections, after the generic entries
    problems: list[str] = field(default_factory=list)
    replays: list[str] = field(default_factory=list)
    studies_note: str = ""  # why no study is linked, and how to link one


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


def _entries_markdown(entries: list[Entry]) -> list[str]:
    lines: list[str] = []
    for e in entries:
        links = ", ".join(f"[{f}]({f})" for f in e.files)
        lines.append(f"### {e.title}\n\n{links}\n")
        if e.image:
            lines.append(f"![{e.title}]({e.image})\n")
            if e.caption:
                lines.append(f"*{e.caption}*\n")
        lines += [f"- {n}" for n in e.notes]
        if e.notes:
            lines.append("")
    return lines


def index_markdown(d: IndexData) -> str:
    title = d.manifest.get("grid", "run")
    lines = [f"# Report: {title}", "", f"Run directory: `{d.run_dir}`", ""]
    head, missing = _cell_lines(d.cells)
    lines += ["## Figures and tables", ""] + _entries_markdown(d.entries)
    for part in d.parts:
        lines += [f"## {part.title}", ""] + (part.front.markdown() if part.front else []) + _entries_markdown(
            part.entries)
    if d.studies_note:
        lines += ["## Studies", "", d.studies_note, ""]
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
    origin = provenance_lines(d.cells, d.manifest)
    if origin:
        lines += ["", "## Which commits trained the cells", "", *origin]
    lines += ["", "## Manifest", "", "| key | value |", "|---|---|"]
    lines += [f"| {k} | `{v}` |" for k, v in _manifest_rows(d.manifest)]
    if not d.manifest:
        lines.append("| (no manifest.json) | |")
    return "\n".join(lines) + "\n"


def markdown_tables(md: str, title: str) -> list[tuple[str, pd.DataFrame]]:
    """The pipe tables of a Markdown page as (caption, frame of cell strings): the caption is
    ``title`` plus the heading above the table. For pages other modules write as Markdown
    only (ablation, calibration), so the index shows them as HTML tables too."""
    out: list[tuple[str, pd.DataFrame]] = []
    heading = ""
    rows: list[list[str]] = []

    def cells(line: str) -> list[str]:
        parts = re.split(r"(?<!\\)\|", line.strip()[1:-1])
        return [p.strip().replace("\\|", "|").replace("**", "").replace("`", "") for p in parts]

    def flush() -> None:
        if len(rows) >= 2 and all(len(r) == len(rows[0]) for r in rows):
            cap = f"{title}: {heading}" if heading and heading != title else title
            out.append((cap, pd.DataFrame(rows[2:], columns=rows[0])))
        rows.clear()

    for line in md.splitlines() + [""]:
        if line.startswith("|") and line.rstrip().endswith("|"):
            rows.append(cells(line))
            continue
        flush()
        if line.startswith("#"):
            heading = line.lstrip("#").strip()
    return out


def small_table(head: list[str], rows: list[list[str]], caption: str) -> str:
    """A small table of already-escaped cell HTML (verdict badges, code) with a caption."""
    h = "".join(f"<th>{html.escape(c)}</th>" for c in head)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return (f"<table><caption>{html.escape(caption)}</caption><thead><tr>{h}</tr></thead>"
            f"<tbody>{body}</tbody></table>")


def _entries_html(entries: list[Entry], anchor: Anchors, toc: TocItems, prefix: str) -> list[str]:
    """Each entry: its heading, figure and caption or file links, notes, HTML block, tables."""
    e = html.escape
    parts = []
    for k, en in enumerate(entries):
        uid = anchor(en.title)
        toc.append((en.title, uid))
        links = ", ".join(f"<a href='{e(f)}'>{e(f)}</a>" for f in en.files)
        notes = "<ul>" + "".join(f"<li>{e(n)}</li>" for n in en.notes) + "</ul>" if en.notes else ""
        parts.append(f"<h3 id='{e(uid)}'>{e(en.title)}</h3>")
        if en.image:
            cap = f"<figcaption>{e(en.caption)}</figcaption>" if en.caption else ""
            img = f"<a href='{e(en.image)}'><img src='{e(en.image)}' alt='{e(en.title)}'></a>"
            parts.append(f"<div class='figrow'><figure>{img}</figure>"
                         f"<div class='side'>{cap}<p>Files: {links}</p>{notes}</div></div>")
        else:
            parts.append(f"<p>Files: {links}</p>")
        if en.html_block is not None:
            parts.append(en.html_block(anchor, toc))
        for j, (caption, frame) in enumerate(en.tables):
            parts.append(scroll_box(html_table(frame, caption, f"{prefix}{k}_{j}")))
        if notes and not en.image:
            parts.append(notes)
    return parts


def index_html(d: IndexData) -> str:
    e = html.escape
    anchor = Anchors()
    toc: list[tuple[str, str, list[tuple[str, str]]]] = []

    def h2(text: str) -> str:
        uid = anchor(text)
        toc.append((text, uid, []))
        return f"<h2 id='{e(uid)}'>{e(text)}</h2>"

    title = e(str(d.manifest.get("grid", "run")))
    parts = [f"<p>Run directory: <code>{e(d.run_dir)}</code></p>", h2("Figures and tables")]
    parts += _entries_html(d.entries, anchor, toc[-1][2], "t")
    for k, part in enumerate(d.parts):
        parts.append(h2(part.title))
        if part.front is not None:
            parts += part.front.html(anchor, toc[-1][2])
        parts += _entries_html(part.entries, anchor, toc[-1][2], f"s{k}_")
    if d.studies_note:
        parts.append(h2("Studies") + f"<p>{e(d.studies_note)}</p>")
    if d.replays:
        parts.append(h2("Replays") + "<ul>" + "".join(
            f"<li><a href='{e(r)}'>{e(r)}</a></li>" for r in d.replays) + "</ul>")
    head, missing = _cell_lines(d.cells)
    parts.append(h2("What this run lacks") + f"<p>{e(head)}</p>")
    if missing:
        keys = ["cell", "method", "N", "p", "seed", "status", "error"]
        parts.append(scroll_box(small_table(keys, [[e(r[k]) for k in keys] for r in missing],
                                       "Cells of the store that are not done, with the last line of their error"),
                                wrap=True))
    else:
        parts.append("<p>Every cell of the store is done.</p>")
    if d.problems:
        parts.append("<ul>" + "".join(f"<li>{e(p)}</li>" for p in d.problems) + "</ul>")
    origin = provenance_lines(d.cells, d.manifest)
    if origin:
        parts.append(h2("Which commits trained the cells") + "".join(f"<p>{e(t)}</p>" for t in origin))
    parts.append(h2("Manifest"))
    rows = [[e(k), f"<code>{e(v)}</code>"] for k, v in _manifest_rows(d.manifest)]
    parts.append(scroll_box(small_table(["key", "value"], rows or [["(no manifest.json)", ""]],
                                   "The run's manifest: versions, git commit and command"), wrap=True))
    nav = toc_html(toc)
    return ("\n".join([f"<!DOCTYPE html><html><head><meta charset='utf-8'><meta name='viewport' "
                       f"content='width=device-width, initial-scale=1'><title>Report: {title}</title>"
                       f"<style>{PAGE_CSS}</style></head><body>", nav, f"<main><h1>Report: {title}</h1>",
                       *parts, "</main></body></html>"]) + "\n")
