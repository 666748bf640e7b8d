"""Pages: `index.html`/`index.md` of a report, the claims block on it, the shared layout.

May import: reports.data, reports.claims.claims, reports.figures, reports.tables.
"""
