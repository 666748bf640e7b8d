"""Pages: `index.html`/`index.md` of a report, the claims block on it, the shared layout.

May import: envs, algorithms, bench, reports.claims, reports.tables, reports.writers,
reports.figures, reports.data, reports.stats (the layers of .importlinter).
"""
