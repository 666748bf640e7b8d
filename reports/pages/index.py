"""The report's front page, ``index.md`` and ``index.html``: every output, its notes, the
claims' verdicts, what the run lacks (cells not done, failed with their error, paper
configurations absent) and the run's manifest (versions, git commit, command).

In ``index.html`` a table of contents (``reports.pages.layout``) links every section, figure
and claim; the content uses the window's width; every figure has its caption beside or
under it and every table (Table I per execution mode, the summary, the claims' checks with
their readable names and numbers, the ablation) is an HTML table with a caption, written by
pandas' ``Styler.to_html`` with every cell escaped, in a box that scrolls when the table is
wider or longer than the window. The claims' checks are grouped per claim, the ones
without enough seeds in one line (``reports.pages.index_claims``). Every link is relative to the report folder and
stays inside it (no ``..``),
so a copied report folder keeps working."""
from __future__ import annotations

import html
import json
import re
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from reports.claims.claims import Claim
from reports.pages.index_claims import badge, grouped_checks_html
from reports.pages.layout import PAGE_CSS, Anchors, html_table, scroll_box, toc_html
from reports.pages.provenance import provenance_lines


@dataclass(frozen=True)
class Entry:
    """One output of the report: a title, its files (first = main view) and notes."""

    title: str
    files: tuple[str, ...]
    notes: tuple[str, ...] = ()
    image: str | None = None  # PNG shown inline in the HTML page
    caption: str = ""  # printed under the figure (index.html, index.md)
    tables: tuple[tuple[str, pd.DataFrame], ...] = ()  # (caption, display strings) -> HTML tables
    checks: pd.DataFrame | None = None  # the claims' checks (claims_frame), grouped per claim in HTML


@dataclass
class IndexData:
    run_dir: str
    manifest: dict[str, Any]
    cells: pd.DataFrame  # all cells of the store
    entries: list[Entry]
    claims: list[Claim]
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


def index_markdown(d: IndexData) -> str:
    title = d.manifest.get("grid", "run")
    lines = [f"# Report: {title}", "", f"Run directory: `{d.run_dir}`", ""]
    head, missing = _cell_lines(d.cells)
    lines += ["## Claims of the paper (Sec. IV)", "", "| claim | verdict |", "|---|---|"]
    lines += [f"| {c.key} | **{c.verdict}** |" for c in d.claims if c.home == "paper"]
    own = [c for c in d.claims if c.home != "paper"]  # reports.claims.method_claims
    if own:
        lines += ["", "## Methods of this run above each baseline", "", "| claim | verdict (run configurations) |",
                  "|---|---|"] + [f"| {c.key} | **{c.verdict}** |" for c in own]
    lines += ["", "Details, numbers and tests: [claims.md](claims.md)", "", "## Figures and tables", ""]
    for e in d.entries:
        links = ", ".join(f"[{f}]({f})" for f in e.files)
        lines.append(f"### {e.title}\n\n{links}\n")
        if e.image:
            lines.append(f"![{e.title}]({e.image})\n")
            if e.caption:
                lines.append(f"*{e.caption}*\n")
        lines += [f"- {n}" for n in e.notes]
        if e.notes:
            lines.append("")
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


def _table(head: list[str], rows: list[list[str]], caption: str) -> str:
    """A small table of already-escaped cell HTML (verdict badges, code) with a caption."""
    h = "".join(f"<th>{html.escape(c)}</th>" for c in head)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return (f"<table><caption>{html.escape(caption)}</caption><thead><tr>{h}</tr></thead>"
            f"<tbody>{body}</tbody></table>")


def index_html(d: IndexData) -> str:
    e = html.escape
    anchor = Anchors()
    toc: list[tuple[str, str, list[tuple[str, str]]]] = []

    def h2(text: str) -> str:
        uid = anchor(text)
        toc.append((text, uid, []))
        return f"<h2 id='{e(uid)}'>{e(text)}</h2>"

    title = e(str(d.manifest.get("grid", "run")))
    parts = [f"<p>Run directory: <code>{e(d.run_dir)}</code></p>", h2("Claims of the paper (Sec. IV)")]
    claims_toc = toc[-1][2]  # each claim's block of checks, nested under the claims' heading
    claim_ids = {c.key: anchor(f"claim {c.key}") for c in d.claims}
    paper, own = [c for c in d.claims if c.home == "paper"], [c for c in d.claims if c.home != "paper"]

    def verdicts(claims: list[Claim], caption: str) -> str:
        return scroll_box(_table(["claim", "key", "verdict"], [
            [f"<a href='#{e(claim_ids[c.key])}'>{e(c.name)}</a>", f"<code>{e(c.key)}</code>", badge(c.verdict)]
            for c in claims], caption))
    parts.append(verdicts(paper, "Verdict of each claim at the paper's configurations (its checks per "
                          "configuration and execution mode under \"Claims of Sec. IV\" below)"))
    if own:  # reports.claims.method_claims
        parts.append(verdicts(own, "Methods of this run above each baseline: verdict at the run's "
                              "configurations (its checks under \"Claims of Sec. IV\" below)"))
    parts.append(h2("Figures and tables"))
    for k, en in enumerate(d.entries):
        uid = anchor(en.title)
        toc[-1][2].append((en.title, uid))
        links = ", ".join(f"<a href='{e(f)}'>{e(f)}</a>" for f in en.files)
        notes = "<ul>" + "".join(f"<li>{e(n)}</li>" for n in en.notes) + "</ul>" if en.notes else ""
        parts.append(f"<h3 id='{e(uid)}'>{e(en.title)}</h3>")
        if en.image:
            cap = f"<figcaption>{e(en.caption)}</figcaption>" if en.caption else ""
            parts.append(f"<div class='figrow'><figure><img src='{e(en.image)}' alt='{e(en.title)}' width='700'>"
                         f"</figure><div class='side'>{cap}<p>Files: {links}</p>{notes}</div></div>")
        else:
            parts.append(f"<p>Files: {links}</p>")
        if en.checks is not None:
            block, claim_toc = grouped_checks_html(en.checks, {c.key: c.verdict for c in d.claims},
                                                   lambda key: claim_ids.get(key) or anchor(f"claim {key}"),
                                                   {c.key for c in own})
            parts.append(block)
            claims_toc += claim_toc
        for j, (caption, frame) in enumerate(en.tables):
            parts.append(scroll_box(html_table(frame, caption, f"t{k}_{j}")))
        if notes and not en.image:
            parts.append(notes)
    if d.studies_note:
        parts.append(h2("Studies") + f"<p>{e(d.studies_note)}</p>")
    if d.replays:
        parts.append(h2("Replays") + "<ul>" + "".join(
            f"<li><a href='{e(r)}'>{e(r)}</a></li>" for r in d.replays) + "</ul>")
    head, missing = _cell_lines(d.cells)
    parts.append(h2("What this run lacks") + f"<p>{e(head)}</p>")
    if missing:
        keys = ["cell", "method", "N", "p", "seed", "status", "error"]
        parts.append(scroll_box(_table(keys, [[e(r[k]) for k in keys] for r in missing],
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
    parts.append(scroll_box(_table(["key", "value"], rows or [["(no manifest.json)", ""]],
                                   "The run's manifest: versions, git commit and command"), wrap=True))
    nav = toc_html(toc)
    return ("\n".join([f"<!DOCTYPE html><html><head><meta charset='utf-8'><meta name='viewport' "
                       f"content='width=device-width, initial-scale=1'><title>Report: {title}</title>"
                       f"<style>{PAGE_CSS}</style></head><body>", nav, f"<main><h1>Report: {title}</h1>",
                       *parts, "</main></body></html>"]) + "\n")
