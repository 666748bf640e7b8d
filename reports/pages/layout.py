"""The look of ``index.html``: a table of contents beside a content column that uses the
window, figures at their natural size up to the column's width, and tables whose cells
wrap so that they fit the column (scrolling inside their own box only as a last resort).

Pure helpers for ``reports.pages.index``: ``PAGE_CSS``; ``Anchors`` (deterministic, unique
element ids from headings); ``toc_html`` (the nested list of links to those ids);
``html_table`` (a frame of display strings as an escaped ``<table>``) and
``scroll_box`` (a table wrapped in a box that scrolls when the table is still wider than
the column once its cells wrap, or longer than the box, header row sticky, so a wide or
long table never widens or stretches the page).
"""
from __future__ import annotations

import html
import re
from collections.abc import Sequence

import pandas as pd

# The TOC is a sticky side column on a wide window and a block on top of a narrow one.
# Figures keep their natural width (the PNG's: 700 px for a paper column, 1400-2040 px
# for the many-panel ones) up to the column's width, with the caption and notes beside them
# when the window has room, else under them; each links to its full-size image. Table
# cells wrap (wide tables hid columns in a scroll box at 1400 px).
PAGE_CSS = """*{box-sizing:border-box}body{font-family:system-ui,sans-serif;margin:0;line-height:1.4;
display:grid;grid-template-columns:16rem minmax(0,1fr)}
nav.toc{position:sticky;top:0;align-self:start;max-height:100vh;overflow-y:auto;padding:1em;
font-size:90%;border-right:1px solid #ddd;background:#fafafa}
nav.toc ul{list-style:none;padding-left:.8em;margin:.2em 0}nav.toc>ul{padding-left:0}
nav.toc a{text-decoration:none}nav.toc a:hover{text-decoration:underline}
main{padding:0 2em 3em 2em;min-width:0}
@media (max-width:900px){body{display:block}nav.toc{position:static;max-height:none;border:0}}
h2{border-bottom:1px solid #ddd;padding-bottom:.1em;margin-top:1.6em}
table{border-collapse:collapse;margin:0}td,th{border:1px solid #ccc;padding:2px 6px;
font-size:90%;vertical-align:top;text-align:left}thead th{position:sticky;top:0;background:#f3f3f3}
caption{caption-side:top;text-align:left;font-size:90%;color:#333;padding:2px 0}
.box{max-width:100%;max-height:40em;overflow:auto;margin:.5em 0 1em 0}
.box td{max-width:40em}td code{word-break:break-all}
.figrow{display:flex;flex-wrap:wrap;gap:.5em 2em;align-items:flex-start}
figure{margin:.5em 0;max-width:100%}img{display:block;max-width:100%;height:auto;border:1px solid #eee}
.side{flex:1 1 18em;max-width:48em}figcaption,.side p,.side li{font-size:90%;color:#333}
.supported{color:#1a7f37}.contradicted{color:#b42318}.undecided{color:#555}
.not-enough-seeds{color:#8a6d00}.verified-by-construction{color:#1a5f7f}
details.claim{margin:.3em 0;border-left:3px solid #ddd;padding-left:.6em}
details.claim>summary{cursor:pointer}.counts{color:#555;font-size:90%}
p.thin{font-size:90%;color:#555;margin:.2em 0 .6em 0}code{font-size:90%}"""


class Anchors:
    """Element ids for headings: a slug of the text, made unique with -2, -3, ... in the
    order asked, so the same page always gets the same ids."""

    def __init__(self) -> None:
        self.used: set[str] = set()

    def __call__(self, text: str) -> str:
        base = re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")[:60].strip("-") or "section"
        out, k = base, 2
        while out in self.used:
            out, k = f"{base}-{k}", k + 1
        self.used.add(out)
        return out


def toc_html(sections: Sequence[tuple[str, str, Sequence[tuple[str, str]]]]) -> str:
    """``<nav>`` of (title, id, [(sub title, sub id), ...]) sections as nested lists."""
    e = html.escape
    items = []
    for title, uid, subs in sections:
        sub = "".join(f"<li><a href='#{e(s_id)}'>{e(s_title)}</a></li>" for s_title, s_id in subs)
        items.append(f"<li><a href='#{e(uid)}'>{e(title)}</a>" + (f"<ul>{sub}</ul>" if sub else "") + "</li>")
    return "<nav class='toc'><b>Contents</b><ul>" + "".join(items) + "</ul></nav>"


def scroll_box(table: str, wrap: bool = False) -> str:
    """``table`` (HTML) inside a box that scrolls when the table is longer than the box, or
    wider than the column even with its cells wrapped; ``wrap`` (long text, e.g. the
    manifest) is kept as a class for callers, every cell wraps."""
    return f"<div class='box{' wrap' if wrap else ''}'>{table}</div>"


def html_table(frame: pd.DataFrame, caption: str, uid: str) -> str:
    """``frame`` (display strings) as an HTML ``<table>`` with ``<caption>``; cells, headers
    and caption escaped. ``uid`` makes the element ids deterministic."""
    sty = (frame.style.hide(axis="index").format(escape="html")
           .format_index(escape="html", axis=1).set_caption(html.escape(caption))
           .set_uuid("".join(c if c.isalnum() else "_" for c in uid)))
    return sty.to_html(table_attributes='class="data"')
